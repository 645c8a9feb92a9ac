// method=auto's quick case on a Cartesian grid (methods/hybrid.hpp, auto_sphere_quick) must
// make the choice of the full cost model (path_costs): for every sphere it takes, the path
// it reports is the one path_costs gives (fast, pmm cheaper, else exact). A quick case that
// chose otherwise would make a sphere's deposits depend on which of the two it met.
#include "engine_mesh.hpp"
#include "methods/hybrid.hpp"
#include "methods/rectilinear.hpp"
#include "particle_grid.hpp"

#include <vfe/kernels/divided.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <span>

namespace vfe::detail {
namespace {

// The bank's memo (the last two templates a thread was given) gives every sphere the
// template the auto rule gives it: spheres of a few sizes in cells of a few volumes, in
// random order, and a second bank, whose id makes the memo's entries stale.
TEST(TemplateMemo, GivesTheAutoRulesTemplate) {
  Options opts;
  TemplateCache cache;
  std::mt19937_64 rng(5);
  const double diameters[] = {0.0006, 0.001, 0.00100000001, 0.0012}, volumes[] = {8e-9, 1e-9, 2.7e-11};
  TemplateMemo memo;
  int changed = 0;
  const kernels::ParticleTemplate* previous = nullptr;
  for (int round = 0; round < 2; ++round) {
    // Each prepare gives a new bank (and id), over the same or other sizes.
    const TemplateBank bank = cache.prepare(opts, 0.0006, round == 0 ? 0.0012 : 0.001, 2.7e-11, 8e-9);
    ASSERT_GT(bank.templates.size(), 2u);
    for (int i = 0; i < 4000; ++i) {
      const double d = diameters[rng() % (round == 0 ? 4 : 3)], v = volumes[rng() % 3];
      const kernels::ParticleTemplate& t = bank.template_for(d, v, memo);
      ASSERT_EQ(&t, &bank.template_for(d, v)) << "d " << d << " v " << v;
      changed += &t != previous;
      previous = &t;
    }
    EXPECT_EQ(memo.bank, bank.id);
  }
  EXPECT_GT(changed, 1000);  // the sizes alternate: both entries and their replacement served
}

// The cache gives a template of kPointTreeMinPoints points or more (whatever size was asked
// for) its tree of balls, of the template's own points: pmm on a polyMesh places a ball that
// one cell holds at once. A smaller template gets none.
TEST(TemplateCache, LargeTemplatesGetTheirTreeOfBalls) {
  Options opts;
  TemplateCache cache;
  for (const TemplateFamily family : {TemplateFamily::fibonacci, TemplateFamily::spherical, TemplateFamily::voxel}) {
    opts.template_family = family;
    for (const std::int64_t n : {std::int64_t(27), TemplateCache::kPointTreeMinPoints - 1,
                                 TemplateCache::kPointTreeMinPoints, std::int64_t(1000)}) {
      const kernels::ParticleTemplate& t = cache.get(opts, n);
      if (static_cast<std::int64_t>(t.size()) < TemplateCache::kPointTreeMinPoints) {
        EXPECT_TRUE(t.tree.empty()) << n;
        continue;
      }
      ASSERT_FALSE(t.tree.empty()) << n;
      EXPECT_EQ(t.tree.nodes.front().count, t.size());
      std::vector<Eigen::Vector3d> a = t.points, b = t.tree.points;
      const auto less = [](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
        return std::lexicographical_compare(x.data(), x.data() + 3, y.data(), y.data() + 3);
      };
      std::sort(a.begin(), a.end(), less);
      std::sort(b.begin(), b.end(), less);
      EXPECT_EQ(a, b) << n;
    }
  }
}

// Where every cell has one volume, a bank of several templates gives a sphere its template by
// comparing its diameter with the diameters at which the auto step rises: for random
// diameters, each threshold and its neighbouring doubles, the template is the one the auto
// rule gives (auto_step); a sphere in a cell of another volume still gets the rule's.
TEST(TemplateBank, ThresholdsGiveTheAutoRulesTemplate) {
  Options opts;
  TemplateCache cache;
  const double v = 8e-9;
  // The cache keeps each step's threshold: later banks over other ranges of sizes, inside,
  // beyond and across the first, reuse them and find the rest.
  const double ranges[][2] = {{0.0005, 0.0015}, {0.0007, 0.0013}, {0.0004, 0.0011}, {0.0003, 0.002}};
  for (const auto& range : ranges) {
    const double d_min = range[0], d_max = range[1];
    SCOPED_TRACE(d_min);
    const TemplateBank bank = cache.prepare(opts, d_min, d_max, v, v);
    ASSERT_GT(bank.templates.size(), 3u);
    ASSERT_EQ(bank.thresholds.size(), bank.templates.size() - 1);
    EXPECT_EQ(bank.threshold_cell_volume, v);
    auto rules = [&](double d, double volume) -> const kernels::ParticleTemplate& {
      const std::int64_t k = auto_step(d, volume, bank.rule) - bank.first_step;
      const auto last = static_cast<std::int64_t>(bank.templates.size()) - 1;
      return *bank.templates[static_cast<std::size_t>(std::clamp<std::int64_t>(k, 0, last))];
    };
    std::vector<double> diameters = {d_min, d_max};
    for (std::size_t k = 0; k < bank.thresholds.size(); ++k) {
      const double t = bank.thresholds[k];
      if (k > 0) {
        EXPECT_GT(t, bank.thresholds[k - 1]);
      }
      diameters.insert(diameters.end(), {t, std::nextafter(t, 0.0), std::nextafter(t, 1.0)});
    }
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> u(d_min, d_max);
    for (int i = 0; i < 100000; ++i) diameters.push_back(u(rng));
    TemplateMemo memo;
    for (const double d : diameters) {
      ASSERT_EQ(&bank.template_for(d, v), &rules(d, v)) << "d " << d;
      ASSERT_EQ(&bank.template_for(d, v, memo), &rules(d, v)) << "d " << d;
      ASSERT_EQ(&bank.template_for(d, 2 * v), &rules(d, 2 * v)) << "d " << d;  // no thresholds for this volume
    }
  }
  // Cells of several volumes: no thresholds.
  EXPECT_TRUE(cache.prepare(opts, 0.0005, 0.0015, v / 2, v).thresholds.empty());
}

// The ball's box of cells that method=auto's model locates once on a graded grid, and exact
// takes from it, is what exact located itself: the one cell of rectilinear_one_cell, else per
// axis the cells of c - r and c + r (periodic axes continued), for balls beyond the grid,
// wider than it and with c +- r on a node.
TEST(BallBox, IsTheOneCellOrTheCellsOfTheBallsEnds) {
  const kernels::ParticleTemplate divided = kernels::make_divided_template();
  std::array<std::vector<double>, 3> nodes;
  for (auto& x : nodes) {
    x = {-0.003};
    for (double dx = 0.0004; x.back() < 0.012; dx *= 1.2) x.push_back(x.back() + dx);
  }
  const RectilinearGrid grid(nodes);
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(-0.006, 0.016), size(0.00005, 0.004);
  std::int64_t one = 0, many = 0, node_ends = 0;
  for (const unsigned periodic : {0u, 5u})
    for (const bool fast_path : {true, false}) {
      Options opts;
      opts.periodic = periodic;
      opts.fast_path = fast_path;
      const RectilinearContext ctx{MethodContext{opts, TemplateBank{}, divided}, grid};
      for (int i = 0; i < 20000; ++i) {
        Eigen::Vector3d c(u(rng), u(rng), u(rng));
        double r = size(rng);
        if (i % 5 == 0) {  // an end on a node
          const int d = i % 3;
          const auto& x = nodes[static_cast<std::size_t>(d)];
          r = 0.3 * (x[7] - x[6]);
          c[d] = x[6 + static_cast<std::size_t>(i % 2)] + (i % 10 < 5 ? r : -r);
          ++node_ends;
        }
        const BallBox box = ball_box(ctx, c, r);
        ASSERT_EQ(box.one_cell, rectilinear_one_cell(ctx, c, Eigen::Vector3d::Constant(r))) << "ball " << i;
        if (box.one_cell >= 0) {
          ++one;
          continue;
        }
        ++many;
        for (int d = 0; d < 3; ++d) {
          const bool wraps = (periodic >> d) & 1u;
          const auto index = [&](double x) { return wraps ? periodic_axis_index(grid, d, x) : grid.axis_index(d, x); };
          ASSERT_EQ(box.lo[d], index(c[d] - r)) << "ball " << i << " axis " << d;
          ASSERT_EQ(box.hi[d], index(c[d] + r)) << "ball " << i << " axis " << d;
        }
      }
    }
  EXPECT_GT(one, 500);  // fast_path=1 only
  EXPECT_GT(many, 10000);
  EXPECT_GT(node_ends, 10000);
}

TEST(HybridQuick, TakesTheFullModelsPathForEverySphereItTakes) {
  Options opts;
  TemplateCache cache;
  const kernels::ParticleTemplate divided = kernels::make_divided_template();
  int took[3] = {0, 0, 0}, declined = 0;
  for (const double h : {0.001, 0.002}) {
    const CartesianGridSpec spec{{0, 0, 0}, {h, h, h}, {12, 12, 12}};
    const EngineMesh mesh(spec);
    for (const std::int64_t n : {35, 300, 815}) {
      const kernels::ParticleTemplate* t = &cache.get(opts, n);
      TemplateBank bank;
      bank.templates = std::span<const kernels::ParticleTemplate* const>(&t, 1);
      bank.fixed = true;
      const Context ctx{MethodContext{opts, bank, divided}, *mesh.cartesian()};
      const PmmQuick quick(ctx);
      std::mt19937_64 rng(static_cast<std::uint64_t>(n) + 7);
      std::uniform_real_distribution<double> at(0.0, 12 * h), size(0.05 * h, 0.7 * h);
      for (int i = 0; i < 3000; ++i) {
        const double r = size(rng);
        const Particle p{i, Eigen::Vector3d(at(rng), at(rng), at(rng)), r, 4.0 / 3.0 * std::numbers::pi * r * r * r,
                         nullptr, static_cast<std::uint64_t>(i)};
        Scratch model;
        const PathCosts k = path_costs(ctx, model, p);
        const int expected = k.fast ? 0 : (k.pmm < k.exact ? 1 : 2);
        Scratch s;
        double added = 0;
        if (!auto_sphere_quick(quick, s, p, [&](std::int64_t, double v) { added += v; })) {
          EXPECT_EQ(s.auto_fast + s.auto_pmm + s.auto_exact, 0);
          ++declined;
          continue;
        }
        ASSERT_EQ(s.auto_fast + s.auto_pmm + s.auto_exact, 1);
        const int path = s.auto_fast ? 0 : (s.auto_pmm ? 1 : 2);
        EXPECT_EQ(path, expected) << "h " << h << ", n " << n << ", sphere " << i << ": pmm " << k.pmm << " ns, exact "
                                  << k.exact << " ns";
        if (path != 1) {  // exact, fast: the ball inside the grid
          EXPECT_NEAR(added, p.volume, 1e-13 * p.volume);
        }
        ++took[path];
      }
    }
  }
  // Each path is taken, and the quick case serves most spheres.
  EXPECT_GT(took[0], 0);
  EXPECT_GT(took[1], 0);
  EXPECT_GT(took[2], 0);
  EXPECT_GT(took[0] + took[1] + took[2], 2 * declined);
}

}  // namespace
}  // namespace vfe::detail

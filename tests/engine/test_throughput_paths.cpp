// The fast paths against the general ones they stand in for: pmm's counting per octant
// against locating every sub-element (fast_path=0), and direct's fused validate-and-deposit
// pass against the general particle loop (accumulation=atomic takes it). The general paths
// are the references: a sub-element in another cell moves V/n, far above the tolerances.
#include "accumulator.hpp"
#include "cell_bins.hpp"
#include "particles.hpp"
#include "particle_grid.hpp"

#include <vfe/kernels/particle_template.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <thread>

namespace vfe::test {
namespace {

void expect_same_field(const std::vector<double>& a, const std::vector<double>& b, double tol, const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  int bad = 0;
  for (std::size_t c = 0; c < a.size() && bad < 5; ++c)
    if (!(std::abs(a[c] - b[c]) <= tol)) {
      ADD_FAILURE() << what << ": cell " << c << ": " << a[c] << " against " << b[c];
      ++bad;
    }
}

/// Spheres of radius r whose template points lie within 1e-13 of a cell face: centre =
/// face - r R q_i (+- 1e-13) along one axis, the other axes random, q_i of the template of
/// `points` points and R the identity (orientation=none) or, banked, sphere i's rotation
/// from the bank (orientation=random, seed 0, the key its index).
Particles near_face_spheres(double h, int cells, double r, int count, bool banked = false, int points = 45) {
  const kernels::ParticleTemplate t = kernels::make_fibonacci_template(points);
  std::mt19937_64 rng(banked ? 4 : 3);
  std::uniform_real_distribution<double> pos(2 * h, (cells - 2) * h);
  Particles p;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d& q0 = t.points[static_cast<std::size_t>(i) % t.size()];
    const Eigen::Vector3d q = banked ? Eigen::Vector3d(kernels::banked_random_rotation(std::uint64_t(i), 0) * q0) : q0;
    double c[3] = {pos(rng), pos(rng), pos(rng)};
    const int d = i % 3;
    const double face = h * std::round(c[d] / h);
    c[d] = face - r * q[d] + (i % 2 ? 1e-13 : -1e-13);
    p.add(c[0], c[1], c[2], r);
  }
  return p;
}

/// A scene of pmm spheres and the options it runs with.
struct PmmCase {
  const char* name;
  Particles p;
  std::string options;
};

TEST(PmmCounting, EveryCellEqualsLocatingEverySubElement) {
  std::vector<PmmCase> cases;
  // chi = 4, 2, 1.5 and 1 (radius 1/8, 1/4, 1/3, 1/2 of the cell), random orientations:
  // particle_grid=auto's templates of each counting code (up to 64 points, 65 to 512
  // compared one by one, more in groups).
  for (const double r : {0.125, 0.25, 1.0 / 3.0, 0.5})
    cases.push_back({"random", random_spheres(11, 3000, 1.0, 9.0, r, r), ""});
  // Several templates: each sphere's from the bank's diameter thresholds.
  cases.push_back({"polydisperse", random_spheres(12, 3000, 1.0, 9.0, 0.15, 0.5), ""});
  cases.push_back({"near faces", near_face_spheres(1.0, 10, 0.25, 3000), " orientation=none particle_grid=45"});
  cases.push_back({"near faces chi 1", near_face_spheres(1.0, 10, 0.5, 3000), " orientation=none particle_grid=45"});
  cases.push_back({"near faces, banked rotations", near_face_spheres(1.0, 10, 0.25, 3000, true),
                   " orientation=random seed=0 particle_grid=45"});
  cases.push_back({"near faces, banked rotations, 120 points", near_face_spheres(1.0, 10, 1.0 / 3.0, 3000, true, 120),
                   " orientation=random seed=0 particle_grid=120"});
  cases.push_back({"beyond the grid", random_spheres(13, 2000, -0.5, 10.5, 0.2, 0.4), " outside=nearest"});
  cases.push_back({"periodic", random_spheres(14, 2000, -0.5, 10.5, 0.2, 0.4), " periodic=xyz"});
  cases.push_back({"block", random_spheres(15, 3000, 1.0, 9.0, 0.15, 0.5), ""});
  cases.push_back({"block near faces", near_face_spheres(1.0, 10, 0.25, 3000), " orientation=none particle_grid=45"});
  for (const PmmCase& c : cases) {
    SCOPED_TRACE(c.name);
    // The same box as a block of a larger grid (first_cell, one of them negative): its
    // cells' positions come from the larger grid's indices, which the quick cases follow.
    CartesianGridSpec spec = grid(1.0, 10, 10, 10);
    if (std::string(c.name).starts_with("block")) spec.first_cell = {-1, 0, 2}, spec.origin = {1.0, 0, -2.0};
    Engine counting(spec), locating(spec);
    const std::vector<double> a = run(counting, c.p, "method=pmm threads=1" + c.options);
    const std::vector<double> b = run(locating, c.p, "method=pmm threads=1 fast_path=0" + c.options);
    const double v = c.p.volume() / double(c.p.radii.size());
    expect_same_field(a, b, 1e-13 * v, c.name);
    if (std::string(c.name).find("near faces") != std::string::npos)  // every particle has a point 1e-13 from a face
      EXPECT_EQ(counting.last_report_value("counted_particles"), 0.0);
    else
      EXPECT_GT(counting.last_report_value("counted_particles"), 0.3 * double(c.p.radii.size()));
    EXPECT_EQ(locating.last_report_value("counted_particles"), 0.0);
    // The templates the spheres took (several for the polydisperse scene: one counting
    // call per split set and template).
    EXPECT_EQ(counting.last_report().particle_grid_min, locating.last_report().particle_grid_min);
    EXPECT_EQ(counting.last_report().particle_grid_max, locating.last_report().particle_grid_max);
    EXPECT_NEAR(total(a), c.p.volume(), 1e-12 * c.p.volume());
    EXPECT_EQ(counting.last_report().outside_particles, locating.last_report().outside_particles);
  }
}

// The counts from the template's projections on the rotation bank start once an engine has
// computed a million spheres; from then on every cell is still the one locating every
// sub-element gives, near faces included (every sphere there refused and located in double).
TEST(PmmCounting, ProjectedCountsEqualLocatingEverySubElement) {
  std::vector<PmmCase> cases;
  cases.push_back({"random, chi 2", random_spheres(31, 4000, 1.0, 9.0, 0.25, 0.25), ""});
  cases.push_back({"random, chi 4", random_spheres(32, 4000, 1.0, 9.0, 0.125, 0.125), ""});
  cases.push_back({"near faces, banked rotations", near_face_spheres(1.0, 10, 0.25, 4000, true),
                   " orientation=random seed=0 particle_grid=45"});
  cases.push_back({"64 points", random_spheres(33, 4000, 1.0, 9.0, 0.25, 0.25), " particle_grid=64"});
  for (const PmmCase& c : cases) {
    SCOPED_TRACE(c.name);
    Engine counting(grid(1.0, 10, 10, 10)), locating(grid(1.0, 10, 10, 10));
    const std::string options = "method=pmm threads=2" + c.options;
    counting.configure(options);
    std::vector<double> a(static_cast<std::size_t>(counting.cell_count()));
    counting.compute(c.p.view(), a);
    EXPECT_EQ(counting.last_report_value("projected_counts"), 0.0) << "a small first compute builds no projections";
    std::int64_t served = std::int64_t(c.p.radii.size());
    while (served < detail::TemplateCache::kSpheresBeforeProjections) {
      counting.compute(c.p.view(), a);
      served += std::int64_t(c.p.radii.size());
    }
    EXPECT_EQ(counting.last_report_value("projected_counts"), 1.0);
    const std::vector<double> b = run(locating, c.p, "method=pmm threads=1 fast_path=0" + c.options);
    const double v = c.p.volume() / double(c.p.radii.size());
    expect_same_field(a, b, 1e-13 * v, c.name);
    if (std::string(c.name).find("near faces") != std::string::npos)
      EXPECT_EQ(counting.last_report_value("counted_particles"), 0.0);
    else
      EXPECT_GT(counting.last_report_value("counted_particles"), 0.3 * double(c.p.radii.size()));
  }
  // Spheres of another size, on an engine past the million: the new template's projections
  // replace the old ones at once, and the cells are still the straightforward ones.
  {
    Engine drifting(grid(1.0, 10, 10, 10));
    drifting.configure("method=pmm threads=2");
    const Particles before = random_spheres(35, 4000, 1.0, 9.0, 0.25, 0.25);
    const Particles after = random_spheres(36, 4000, 1.0, 9.0, 0.125, 0.125);
    std::vector<double> out(static_cast<std::size_t>(drifting.cell_count()));
    for (std::int64_t served = 0; served < detail::TemplateCache::kSpheresBeforeProjections;
         served += std::int64_t(before.radii.size()))
      drifting.compute(before.view(), out);
    EXPECT_EQ(drifting.last_report_value("projected_counts"), 1.0);
    const double grid_before = drifting.last_report().particle_grid_max;
    drifting.compute(after.view(), out);
    EXPECT_NE(drifting.last_report().particle_grid_max, grid_before);  // another template
    EXPECT_EQ(drifting.last_report_value("projected_counts"), 1.0);
    Engine locating(grid(1.0, 10, 10, 10));
    expect_same_field(out, run(locating, after, "method=pmm threads=1 fast_path=0"),
                      1e-13 * after.volume() / double(after.radii.size()), "after the size changed");
  }
  // Rotations not from the bank: no projections, however many spheres.
  const Particles p = random_spheres(34, 4000, 1.0, 9.0, 0.25, 0.25);
  Engine unbanked(grid(1.0, 10, 10, 10));
  unbanked.configure("method=pmm rotation_bank=0");
  std::vector<double> out(static_cast<std::size_t>(unbanked.cell_count()));
  for (std::int64_t served = 0; served < 2 * detail::TemplateCache::kSpheresBeforeProjections;
       served += std::int64_t(p.radii.size()))
    unbanked.compute(p.view(), out);
  EXPECT_EQ(unbanked.last_report_value("projected_counts"), 0.0);
}

TEST(FusedDirect, EqualsTheGeneralLoopUnderEveryOutsidePolicy) {
  const Particles inside = random_spheres(21, 5000, 0.3, 9.7, 0.05, 0.3);
  const Particles spilling = random_spheres(22, 5000, -1.0, 11.0, 0.05, 0.3);
  for (const char* policy : {"nearest", "centre", "drop"})
    for (const char* periodic : {"none", "x", "xyz"})
      for (const Particles* p : {&inside, &spilling}) {
        const std::string o = std::string("method=direct threads=2 outside=") + policy + " periodic=" + periodic;
        SCOPED_TRACE(o);
        Engine fused(grid(0.5, 20, 20, 20)), general(grid(0.5, 20, 20, 20));
        const std::vector<double> a = run(fused, *p, o);
        const std::vector<double> b = run(general, *p, o + " accumulation=atomic");
        expect_same_field(a, b, 1e-15 * p->volume(), o);
        EXPECT_EQ(fused.last_report_value("fused_pass"), 1.0);
        EXPECT_EQ(general.last_report_value("fused_pass"), 0.0);
        const Report& ra = fused.last_report();
        const Report& rb = general.last_report();
        EXPECT_EQ(ra.particle_volume, rb.particle_volume);  // the same reduction
        EXPECT_EQ(ra.outside_particles, rb.outside_particles);
        EXPECT_EQ(ra.sub_elements, rb.sub_elements);
        // The same dropped shares added in another order (threads): within the summation
        // bound n eps sum (1e-15 of the particles' volume was below it, and failed once).
        const double n = double(p->radii.size());
        EXPECT_NEAR(ra.dropped_volume, rb.dropped_volume, n * std::numeric_limits<double>::epsilon() * rb.dropped_volume);
      }
}

TEST(FusedDirect, BadParticlesAndOutsideErrorsLeaveTheFieldAndTheNextComputeIntact) {
  Particles p = random_spheres(23, 3000, 0.5, 9.5, 0.1, 0.3);
  Engine e(grid(1.0, 10, 10, 10));
  const std::vector<double> good = run(e, p, "method=direct");
  Particles bad = p;
  bad.radii[1234] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> out(e.cell_count(), 7.0);
  expect_compute_fails(e, bad, out, VFE_ERROR_INVALID_ARGUMENT, "particle 1234");
  for (const double x : out) ASSERT_EQ(x, 7.0);  // nothing written
  Particles outside = p;
  outside.centres[3 * 99] = 20.0;
  e.configure("outside=error");
  EXPECT_THROW(e.compute(outside.view(), out), Error);
  for (const double x : out) ASSERT_EQ(x, 7.0);
  e.configure("outside=nearest");
  e.compute(p.view(), out);
  EXPECT_EQ(out, good);  // nothing of the failed computes remains
}

/// The same spheres as records of x, y, z, r, id (strides of 5 doubles, not packed).
struct Records {
  std::vector<double> values;
  explicit Records(const Particles& p) {
    for (std::size_t i = 0; i < p.radii.size(); ++i)
      values.insert(values.end(), {p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2], p.radii[i], double(i)});
  }
  ParticleView view() const {
    ParticleView v;
    v.n = static_cast<std::int64_t>(values.size() / 5);
    v.centres = values.data();
    v.radii = values.data() + 3;
    v.centre_stride = v.radius_stride = 5;
    return v;
  }
};

TEST(FusedDirect, EqualsTheGeneralLoopForAnyCountStrideAndThreadCount) {
  // Counts that end in every tail of the four-lane steps and in partial chunks of 256.
  for (const int n : {1, 3, 6, 257, 4099})
    for (const int threads : {1, 2})
      for (const bool strided : {false, true})
        for (const char* periodic : {"none", "y"}) {
          const Particles p = random_spheres(40 + n, n, -0.6, 10.6, 0.05, 0.6);
          const Records records(p);
          const std::string o = "method=direct outside=nearest alpha_min=0.3 threads=" + std::to_string(threads) +
                                " periodic=" + periodic;
          SCOPED_TRACE(o + " n=" + std::to_string(n) + (strided ? " strided" : ""));
          Engine fused(grid(0.5, 20, 20, 20)), general(grid(0.5, 20, 20, 20));
          fused.configure(o + " accumulation=private");  // auto takes atomics for few particles
          general.configure(o + " accumulation=atomic");
          std::vector<double> a(fused.cell_count(), -1.0), b(general.cell_count(), -1.0);
          fused.compute(strided ? records.view() : p.view(), a);
          general.compute(p.view(), b);
          expect_same_field(a, b, 1e-15 * p.volume(), o);
          EXPECT_EQ(fused.last_report_value("fused_pass"), 1.0);
          const Report& ra = fused.last_report();
          const Report& rb = general.last_report();
          EXPECT_EQ(ra.particle_volume, rb.particle_volume);
          EXPECT_EQ(ra.outside_particles, rb.outside_particles);
          EXPECT_EQ(ra.sub_elements, rb.sub_elements);
          // The field's facts from the merge's pass against the general loop's separate one.
          const double bound = double(fused.cell_count()) * std::numeric_limits<double>::epsilon() * p.volume();
          EXPECT_NEAR(ra.deposited_volume, rb.deposited_volume, bound);
          EXPECT_NEAR(ra.deposited_volume, total(a), bound);
          EXPECT_NEAR(ra.clipped_volume, rb.clipped_volume, bound);
          EXPECT_EQ(fused.last_report_value("overfull_cells"), general.last_report_value("overfull_cells"));
          EXPECT_NEAR(fused.last_report_value("overfull_volume"), general.last_report_value("overfull_volume"), bound);
          if (n > 1000) {  // the scene is dense enough to test the facts
            EXPECT_GT(fused.last_report_value("overfull_cells"), 0.0);
            EXPECT_GT(ra.clipped_volume, 0.0);
          }
        }
}

TEST(FusedDirect, ABadParticleAnywhereFailsTheComputeAndLeavesTheOutputAlone) {
  const Particles p = random_spheres(24, 3001, 0.5, 9.5, 0.1, 0.3);
  // The first of a range, the middle of a chunk, a four-lane step's tail in the last
  // partial chunk, the last particle.
  for (const int at : {0, 1234, 2998, 3000})
    for (const char* options : {"method=direct threads=1", "method=direct threads=2",
                                "method=direct threads=2 periodic=xyz", "method=pmm threads=2"}) {
      SCOPED_TRACE(std::string(options) + " at " + std::to_string(at));
      Engine e(grid(1.0, 10, 10, 10));
      const std::vector<double> good = run(e, p, options);
      for (const int coordinate : {1, 3}) {  // a NaN centre's y, a NaN radius
        Particles bad = p;
        (coordinate == 3 ? bad.radii[at] : bad.centres[3 * at + coordinate]) = std::numeric_limits<double>::quiet_NaN();
        if (at + 2 < 3001) bad.radii[at + 2] = -1.0;  // a later bad particle is not the one named
        std::vector<double> out(e.cell_count(), 7.0);
        expect_compute_fails(e, bad, out, VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(at) + ":");
        for (const double x : out) ASSERT_EQ(x, 7.0);
      }
      std::vector<double> again(e.cell_count(), -1.0);
      e.compute(p.view(), again);
      // Two threads may split the particles differently between computes: the same cells,
      // added in another order.
      expect_same_field(again, good, 1e-15 * p.volume(), "after the failed computes");
    }
}

// pmm's, auto's and exact's fused passes validate the spheres as they go, chunk by chunk,
// instead of in a pass of their own; pmm's and auto's take their template bank from the
// last compute's diameters. The reference: the general loop (accumulation=atomic), which
// validates first. The report's particle volume is validation's sum: equal only when the
// same chunks are summed in the same tree.
TEST(FusedPasses, ValidateAsTheyGoWithTheReportOfAValidationFirst) {
  for (const char* method : {"pmm", "auto", "exact"})
    for (const int n : {1, 6, 257, 4099})
      for (const int threads : {1, 2})
        for (const bool strided : {false, true}) {
          const Particles p = random_spheres(60 + n, n, -0.6, 10.6, 0.1, 0.4);  // some beyond the grid
          const Records records(p);
          const std::string o = std::string("method=") + method + " outside=nearest threads=" + std::to_string(threads);
          SCOPED_TRACE(o + " n=" + std::to_string(n) + (strided ? " strided" : ""));
          Engine fused(grid(1.0, 10, 10, 10)), general(grid(1.0, 10, 10, 10));
          fused.configure(o + " accumulation=private");
          general.configure(o + " accumulation=atomic");
          std::vector<double> a(fused.cell_count(), -1.0), b(general.cell_count(), -1.0);
          for (int compute = 0; compute < 2; ++compute) {  // the second takes the first's diameters
            fused.compute(strided ? records.view() : p.view(), a);
            general.compute(p.view(), b);
            expect_same_field(a, b, 1e-13 * p.volume(), o);
            const Report& ra = fused.last_report();
            const Report& rb = general.last_report();
            EXPECT_EQ(ra.particle_volume, rb.particle_volume);
            EXPECT_EQ(ra.outside_particles, rb.outside_particles);
            // The same bank. (Not the same sub-element count: with several templates the
            // chunks' windows take the bank's widest reach, so a sphere the general loop
            // puts in one cell may be counted, its other octants given nothing.)
            EXPECT_EQ(ra.particle_grid_min, rb.particle_grid_min);
            EXPECT_EQ(ra.particle_grid_max, rb.particle_grid_max);
            if (n > 1000) {
              EXPECT_GT(ra.outside_particles, 0);
            }
          }
        }
}

// Spheres that change size between computes: the pass that took the last compute's
// diameters for its bank is done again with the bank of the new ones. Every compute equals,
// to the bit (one thread), a new engine's first compute of the same spheres, which takes its
// diameters from the radii before the pass. A compute of no spheres leaves no diameters to
// take (a bank of none crashed the next compute).
TEST(FusedPasses, SpheresThatChangeSizeTakeTheBankOfTheirNewSizes) {
  const Particles small = random_spheres(70, 3000, 0.5, 9.5, 0.1, 0.2);
  const Particles large = random_spheres(71, 3000, 0.5, 9.5, 0.25, 0.4);
  Particles same_range = small;  // the same smallest and largest, others changed
  std::size_t lo = 0, hi = 0;
  for (std::size_t i = 0; i < small.radii.size(); ++i) {
    if (small.radii[i] < small.radii[lo]) lo = i;
    if (small.radii[i] > small.radii[hi]) hi = i;
  }
  for (std::size_t i = 0; i < same_range.radii.size(); ++i)
    if (i != lo && i != hi) same_range.radii[i] = 0.5 * (small.radii[lo] + small.radii[hi]);
  for (const char* method : {"pmm", "auto"}) {
    SCOPED_TRACE(method);
    const std::string o = std::string("method=") + method + " threads=1";
    Engine e(grid(1.0, 10, 10, 10));
    e.configure(o);
    std::vector<double> out(e.cell_count());
    double grid_of_small = 0;
    const Particles none;
    for (const Particles* p :
         std::initializer_list<const Particles*>{&none, &small, &large, &small, &same_range, &none, &large, &small}) {
      e.compute(p->view(), out);
      Engine fresh(grid(1.0, 10, 10, 10));
      EXPECT_EQ(out, run(fresh, *p, o));
      EXPECT_EQ(e.last_report().sub_elements, fresh.last_report().sub_elements);
      EXPECT_EQ(e.last_report().particle_grid_max, fresh.last_report().particle_grid_max);
      EXPECT_EQ(e.last_report().particle_volume, fresh.last_report().particle_volume);
      if (p == &small) grid_of_small = double(e.last_report().particle_grid_max);
    }
    Engine check(grid(1.0, 10, 10, 10));
    run(check, large, o);
    EXPECT_NE(double(check.last_report().particle_grid_max), grid_of_small) << "the sizes take another bank";
  }
}

// direct's fused pass with two threads on a grid of kBinnedCells cells sorts its deposits into
// bins by regions of cells. The reference: each sphere's volume added to the cell holding
// its centre by floor, in one loop (outside=drop, no periodic axis), and the general loop
// (accumulation=atomic) under every outside policy and with a periodic axis.
TEST(BinnedDirect, EqualsABruteForceSumAndTheGeneralLoop) {
  const double h = 0.25;
  const int n = static_cast<int>(std::ceil(std::cbrt(double(detail::kBinnedCells))));  // n^3 cells: bins
  ASSERT_GE(std::int64_t(n) * n * n, detail::kBinnedCells);
  // Enough spheres that accumulation=auto takes per-thread sums, not atomics (8 per cell
  // and thread).
  const Particles p = random_spheres(51, 70000, -0.5, n * h + 0.5, 0.02, 0.2);
  std::vector<double> brute(std::size_t(n) * n * n, 0.0);
  double dropped = 0;
  for (std::size_t i = 0; i < p.radii.size(); ++i) {
    const double v = 4.0 / 3.0 * std::numbers::pi * p.radii[i] * p.radii[i] * p.radii[i];
    std::int64_t at[3];
    bool inside = true;
    for (int d = 0; d < 3; ++d) {
      at[d] = static_cast<std::int64_t>(std::floor(p.centres[3 * i + d] / h));
      inside = inside && at[d] >= 0 && at[d] < n;
    }
    if (inside)
      brute[static_cast<std::size_t>(at[0] + n * (at[1] + n * at[2]))] += v;
    else
      dropped += v;
  }
  ASSERT_GT(dropped, 0.0);
  const double tol = 1e-15 * p.volume();
  // Sums over every cell in two orders: within the summation bound cells eps volume.
  const double sum_tol = double(brute.size()) * std::numeric_limits<double>::epsilon() * p.volume();
  // The dropped shares in another order: within n eps dropped.
  const double dropped_tol = double(p.radii.size()) * std::numeric_limits<double>::epsilon() * dropped;
  for (const char* policy : {"drop", "nearest", "centre"})
    for (const char* periodic : {"none", "x"}) {
      const std::string o = std::string("method=direct alpha_min=0.2 outside=") + policy + " periodic=" + periodic;
      SCOPED_TRACE(o);
      Engine binned(grid(h, n, n, n)), general(grid(h, n, n, n));
      const std::vector<double> a = run(binned, p, o + " threads=2");
      const std::vector<double> b = run(general, p, o + " threads=2 accumulation=atomic");
      EXPECT_GE(binned.last_report_value("binned_regions"), 2.0);
      EXPECT_EQ(binned.last_report_value("fused_pass"), 1.0);
      expect_same_field(a, b, tol, o);
      const Report& ra = binned.last_report();
      const Report& rb = general.last_report();
      EXPECT_EQ(ra.particle_volume, rb.particle_volume);
      EXPECT_EQ(ra.outside_particles, rb.outside_particles);
      EXPECT_NEAR(ra.dropped_volume, rb.dropped_volume, dropped_tol);
      EXPECT_NEAR(ra.deposited_volume, total(a), sum_tol);
      EXPECT_NEAR(ra.clipped_volume, rb.clipped_volume, sum_tol);
      EXPECT_GT(ra.clipped_volume, 0.0);
      EXPECT_EQ(binned.last_report_value("overfull_cells"), general.last_report_value("overfull_cells"));
      if (std::string(policy) == "drop" && std::string(periodic) == "none") {
        expect_same_field(a, brute, tol, "against the brute-force sum");
        EXPECT_NEAR(ra.dropped_volume, dropped, dropped_tol);
      }
    }
  // One thread, or private fields asked for: no bins, the same field.
  for (const char* o : {"method=direct outside=drop threads=1", "method=direct outside=drop threads=2 accumulation=private"}) {
    Engine e(grid(h, n, n, n));
    expect_same_field(run(e, p, o), brute, tol, o);
    EXPECT_EQ(e.last_report_value("binned_regions"), 0.0) << o;
  }
  // Below kBinnedCells: no bins.
  Engine small(grid(h, n, n, (detail::kBinnedCells - 1) / (std::int64_t(n) * n)));
  run(small, p, "method=direct outside=drop threads=2");
  EXPECT_EQ(small.last_report_value("binned_regions"), 0.0);
  // A sparse scene (a sphere per 32 cells) keeps the fused pass and its bins under
  // accumulation=auto, where the general loop's atomics would cost more; one per 128
  // cells takes the atomics.
  Particles sparse, sparser;
  const std::size_t cells = brute.size();
  for (std::size_t i = 0; i < cells / 32; ++i) {
    sparse.add(p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2], p.radii[i]);
    if (i < cells / 128) sparser.add(p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2], p.radii[i]);
  }
  Engine e(grid(h, n, n, n));
  const std::vector<double> a = run(e, sparse, "method=direct outside=drop threads=2");
  EXPECT_EQ(e.last_report_value("fused_pass"), 1.0);
  EXPECT_GT(e.last_report_value("binned_regions"), 0.0);
  Engine general(grid(h, n, n, n));
  expect_same_field(a, run(general, sparse, "method=direct outside=drop threads=2 accumulation=atomic"),
                    1e-15 * sparse.volume(), "sparse");
  run(e, sparser, "method=direct outside=drop threads=2");
  EXPECT_EQ(e.last_report_value("fused_pass"), 0.0);
}

TEST(BinnedDirect, ABadParticleLeavesTheOutputAndTheNextComputeIntact) {
  const int n = static_cast<int>(std::ceil(std::cbrt(double(detail::kBinnedCells))));
  const Particles p = random_spheres(52, 70000, 0.0, 0.25 * n, 0.05, 0.2);
  Engine e(grid(0.25, n, n, n));
  const std::vector<double> good = run(e, p, "method=direct threads=2");
  ASSERT_GT(e.last_report_value("binned_regions"), 0.0);
  Particles bad = p;
  bad.radii[15000] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> out(e.cell_count(), 7.0);
  EXPECT_THROW(e.compute(bad.view(), out), Error);
  for (const double x : out) ASSERT_EQ(x, 7.0);
  std::vector<double> again(e.cell_count(), -1.0);
  e.compute(p.view(), again);
  expect_same_field(again, good, 1e-15 * p.volume(), "after the failed compute");
}

// The bins on their own: two threads write more deposits than the pool was sized for, so
// some pages run out and the rest are kept aside; every deposit must still reach its cell
// once. Whole-number volumes: every order of adds gives the same sums exactly.
TEST(CellBins, EveryDepositReachesItsCellOnceWhenThePoolRunsDry) {
  const std::int64_t cells = 3 * (std::int64_t(1) << 16) + 5;
  detail::CellBins bins;
  for (const int round : {0, 1}) {  // the second start reuses the pool
    bins.start(cells, 1000, 2);     // 1000 deposits announced, 40000 written
    ASSERT_GE(bins.regions(), 4);
    std::vector<double> expected(static_cast<std::size_t>(cells) + 1, 0.0);
    std::vector<std::pair<std::int64_t, double>> deposits[2];
    std::mt19937_64 rng(60 + round);
    std::uniform_int_distribution<std::int64_t> cell(0, cells - 1);
    std::uniform_int_distribution<int> volume(1, 9);
    for (auto& d : deposits)
      for (int i = 0; i < 20000; ++i) d.push_back({cell(rng), double(volume(rng))});
    deposits[1].push_back({cells, 5.0});  // the dropped slot, kept aside
    for (const auto& d : deposits)
      for (const auto& [c, v] : d) expected[static_cast<std::size_t>(c)] += v;
    std::thread writers[2];
    for (int slot = 0; slot < 2; ++slot)
      writers[slot] = std::thread([&, slot] {
        detail::BinWriter w = bins.writer(slot);
        for (const auto& [c, v] : deposits[slot])
          if (c == cells)
            w.extra(c, v);
          else
            w.add(static_cast<std::int32_t>(c), v);
      });
    for (std::thread& t : writers) t.join();
    std::size_t aside = 0;
    for (const auto& e : bins.extra()) aside += e.size();
    EXPECT_GT(aside, 1000u);  // the pool ran dry
    std::vector<double> field(static_cast<std::size_t>(cells) + 1, 0.0);
    for (std::int32_t r = 0; r < bins.regions(); ++r) {  // whole blocks of the field's passes, end to end
      EXPECT_EQ(bins.region_begin(r) % detail::kCellBlock, 0);
      EXPECT_EQ(bins.region_begin(r), r == 0 ? 0 : bins.region_end(r - 1));
      bins.add_region(r, field.data());
    }
    EXPECT_EQ(bins.region_end(bins.regions() - 1), cells);
    for (const auto& e : bins.extra())
      for (const auto& d : e) field[static_cast<std::size_t>(d.cell)] += d.volume;
    EXPECT_EQ(field, expected);
  }
}

}  // namespace
}  // namespace vfe::test

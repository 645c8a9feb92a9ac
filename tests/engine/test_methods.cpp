// The methods users compare against, through the engine on Cartesian grids: volume
// conservation under every outside policy, divided's 29 points, gaussian weights,
// porous_cube's limits, the bigParticle rule, cloud-in-cell, the voxel template, options.
#include <vfe/engine.hpp>

#include "particles.hpp"
#include <vfe/measures.hpp>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>
#include <cstring>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using vfe::CartesianGridSpec;
using vfe::Engine;
using vfe::ParticleView;
using vfe::test::grid;
using vfe::test::Particles;
using vfe::test::run;
using vfe::test::total;

namespace {

const char* const kAllMethods[] = {"direct",      "pmm",          "exact",    "divided", "gaussian",
                                   "porous_cube", "big_particle", "trilinear"};

/// n spheres of radius in [rmin, rmax] with centres anywhere in [lo, hi]^3 (fixed seed).
Particles random_particles(int n, double lo, double hi, double rmin, double rmax, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ur(rmin, rmax), uc(lo, hi);
  Particles p;
  for (int i = 0; i < n; ++i) p.add(uc(rng), uc(rng), uc(rng), ur(rng));
  return p;
}

double sphere(double r) { return 4.0 / 3.0 * std::numbers::pi * r * r * r; }

/// The 29 points of a particle by the description (centre; 6 axial and 8 diagonal
/// directions, polar 45 / 135 degrees, azimuth 45 + 90 k degrees, on two shells).
std::vector<Eigen::Vector3d> divided_points(const Eigen::Vector3d& c, double R) {
  std::vector<Eigen::Vector3d> points = {c};
  for (double shell : {0.623926, 0.917902}) {
    for (int axis = 0; axis < 3; ++axis)
      for (double s : {1.0, -1.0}) {
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[axis] = s;
        points.push_back(c + shell * R * d);
      }
    for (double polar : {45.0, 135.0})
      for (int k = 0; k < 4; ++k) {
        const double th = polar * std::numbers::pi / 180, az = (45.0 + 90.0 * k) * std::numbers::pi / 180;
        points.push_back(c + shell * R *
                                 Eigen::Vector3d(std::sin(th) * std::cos(az), std::sin(th) * std::sin(az),
                                                 std::cos(th)));
      }
  }
  return points;
}

}  // namespace

TEST(Methods, EveryMethodConservesVolumeUnderEveryPolicy) {
  // Particles of 0.1 to 1.6 cells in radius, many poking out of the 6^3 mesh or wholly
  // outside it; the small ones take the fast path.
  Engine e(grid(1.0, 6, 6, 6));
  const Particles p = random_particles(400, -1.0, 7.0, 0.1, 1.6, 31);
  for (const char* m : kAllMethods) {
    for (const char* o : {"nearest", "centre", "drop"}) {
      for (const char* extra : {"", " sigma=1.5", " gamma=2.5", " template=voxel particle_grid=200"}) {
        const std::string opts = std::string("method=") + m + " outside=" + o + extra;
        const auto f = run(e, p, opts);
        const auto& rep = e.last_report();
        EXPECT_NEAR(total(f) + rep.dropped_volume, p.volume(), 1e-12 * p.volume()) << opts;
        EXPECT_NEAR(rep.deposited_volume, total(f), 1e-12 * p.volume()) << opts;
        EXPECT_GT(rep.outside_particles, 0) << opts;
        if (std::string(o) != "drop") EXPECT_EQ(rep.dropped_volume, 0.0) << opts;
        else EXPECT_GT(rep.dropped_volume, 0.0) << opts;
        for (double x : f) ASSERT_GE(x, 0.0) << opts;
      }
    }
  }
}

TEST(Methods, DeterministicIsBitwiseIdenticalForOneAndTwoThreads) {
  Engine e(grid(0.5, 16, 16, 16));
  const Particles p = random_particles(1500, 0.0, 8.0, 0.1, 0.6, 32);
  for (const char* m : kAllMethods) {
    const std::string opts = std::string("method=") + m + " deterministic=1";
    const auto one = run(e, p, opts + " threads=1");
    const auto two = run(e, p, opts + " threads=2");
    EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(double))) << m;
  }
}

TEST(Methods, DividedPlacesItsTwentyNinePointsAsSpecified) {
  // A fine grid (cell 0.05 R) puts every point in its own cell; each gets V/29.
  const double h = 0.05, R = 1.0;
  Engine e(grid(h, 60, 60, 60));
  Particles p;
  const Eigen::Vector3d c(1.5123, 1.4871, 1.5049);
  p.add(c[0], c[1], c[2], R);
  const double v = sphere(R);
  // The points from the description: centre; on shells 0.623926 R and 0.917902 R the 6
  // axial directions and 8 at polar 45 / 135 degrees, azimuth 45 + 90 k degrees.
  const std::vector<Eigen::Vector3d> points = divided_points(c, R);
  std::map<std::int64_t, double> expected;
  for (const auto& q : points) {
    const auto i = std::int64_t(std::floor(q[0] / h)), j = std::int64_t(std::floor(q[1] / h)),
               k = std::int64_t(std::floor(q[2] / h));
    expected[i + 60 * (j + 60 * k)] += v / 29;
  }
  ASSERT_EQ(expected.size(), 29u);
  for (const char* orientation : {"random", "none"}) {  // never rotated
    const auto f = run(e, p, std::string("method=divided orientation=") + orientation);
    EXPECT_EQ(e.last_report().particle_grid_max, 29);
    for (std::size_t cell = 0; cell < f.size(); ++cell) {
      const auto it = expected.find(std::int64_t(cell));
      EXPECT_NEAR(f[cell], it == expected.end() ? 0.0 : it->second, 1e-15) << orientation << " cell " << cell;
    }
  }
}

TEST(Methods, DividedPointsOutsideTheMeshGoToTheCentreCell) {
  // Cells of 1 in a 3^3 mesh; particles of radius 0.5 near the x = 0 and y = 0 walls.
  Engine e(grid(1.0, 3, 3, 3));
  for (const Eigen::Vector3d& c : {Eigen::Vector3d(0.2, 1.5, 1.5), Eigen::Vector3d(0.1, 0.8, 1.5),
                                  Eigen::Vector3d(0.05, 0.1, 2.9)}) {
    Particles p;
    p.add(c[0], c[1], c[2], 0.5);
    const double v = sphere(0.5);
    // The rule by hand: a point in the mesh to its cell, a point beyond it to the centre's cell.
    auto cell_of = [](const Eigen::Vector3d& q) {
      const Eigen::Vector3d f = q.array().floor();
      for (int d = 0; d < 3; ++d)
        if (f[d] < 0 || f[d] > 2) return std::int64_t(-1);
      return std::int64_t(f[0] + 3 * (f[1] + 3 * f[2]));
    };
    std::vector<double> expected(27, 0.0);
    double beyond = 0;
    for (const auto& q : divided_points(c, 0.5)) {
      const std::int64_t cell = cell_of(q);
      if (cell < 0) beyond += v / 29;
      expected[cell >= 0 ? cell : cell_of(c)] += v / 29;
    }
    ASSERT_GT(beyond, 0.0);
    for (const char* policy : {"nearest", "centre"}) {  // nearest acts as centre for divided
      const auto f = run(e, p, std::string("method=divided outside=") + policy);
      for (int cell = 0; cell < 27; ++cell) EXPECT_NEAR(f[cell], expected[cell], 1e-15) << policy << " " << cell;
    }
    const auto d = run(e, p, "method=divided outside=drop");
    EXPECT_NEAR(e.last_report().dropped_volume, beyond, 1e-15);
    EXPECT_NEAR(total(d), v - beyond, 1e-15);
  }
  // The second particle tells the rule from the nearest cell: its outer diagonal points
  // at (-0.13, 1.03, z) lie beyond x = 0 next to cell (0, 1, 1), yet go to (0, 0, 1).
  Particles q;
  q.add(0.1, 0.8, 1.5, 0.5);
  const auto by_rule = run(e, q, "method=divided");
  EXPECT_NEAR(by_rule[0 + 3 * (1 + 3 * 1)], 4 * sphere(0.5) / 29, 1e-15);  // 2 axial + 2 diagonal +y points
}

TEST(Methods, GaussianWeightsSumToOneAndFollowTheKernel) {
  // sigma = 0.5 d = R: the cut box reaches 3 R from the centre. Cells of 1, R = 0.4.
  Engine e(grid(1.0, 8, 8, 8));
  const double R = 0.4, sigma = 0.5 * 2 * R;
  Particles p;
  const Eigen::Vector3d c(3.7, 4.05, 4.5);
  p.add(c[0], c[1], c[2], R);
  const auto f = run(e, p, "method=gaussian sigma=0.5");
  const double v = sphere(R);
  EXPECT_NEAR(total(f), v, 1e-15 * 10);
  // Oracle per axis: the normal density's mass per cell, clipped at 3 sigma, by the
  // midpoint rule; normalised; the product per cell.
  auto axis = [&](double x) {
    std::vector<double> w(8, 0.0);
    const int n = 4000;
    for (int cell = 0; cell < 8; ++cell) {
      const double lo = std::max<double>(cell, x - 3 * sigma), hi = std::min<double>(cell + 1, x + 3 * sigma);
      for (int s = 0; hi > lo && s < n; ++s) {
        const double t = lo + (hi - lo) * (s + 0.5) / n;
        w[cell] += (hi - lo) / n * std::exp(-0.5 * (t - x) * (t - x) / (sigma * sigma));
      }
    }
    double sum = 0;
    for (double q : w) sum += q;
    for (double& q : w) q /= sum;
    return w;
  };
  const auto wx = axis(c[0]), wy = axis(c[1]), wz = axis(c[2]);
  double weights = 0;
  for (int k = 0; k < 8; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 8; ++i) {
        const double w = f[i + 8 * (j + 8 * k)] / v;
        weights += w;
        EXPECT_NEAR(w, wx[i] * wy[j] * wz[k], 1e-8) << i << " " << j << " " << k;
        // Nothing beyond the 3 sigma cut.
        if (i + 1 <= c[0] - 3 * sigma || i >= c[0] + 3 * sigma) {
          EXPECT_EQ(w, 0.0);
        }
      }
  EXPECT_NEAR(weights, 1.0, 1e-14);
  // The fast path only when the whole cut kernel lies in one cell.
  Particles small;
  small.add(2.5, 2.5, 2.5, 0.05);  // 3 sigma = 0.15
  run(e, small, "method=gaussian");
  EXPECT_EQ(e.last_report().fast_path_particles, 1);
  run(e, small, "method=gaussian sigma=4");  // 3 sigma = 1.2
  EXPECT_EQ(e.last_report().fast_path_particles, 0);
}

TEST(Methods, PorousCubeIsExactBoxOverlapAndTendsToDirect) {
  Engine e(grid(0.5, 12, 12, 12));
  const Particles p = random_particles(300, 1.0, 5.0, 0.1, 0.5, 33);  // cubes inside the mesh
  // Oracle: the overlap of each cube with each cell, from the interval lengths.
  const double gamma = 1.7;
  const auto f = run(e, p, "method=porous_cube gamma=1.7 deterministic=1");
  std::vector<double> ref(f.size(), 0.0);
  for (std::size_t q = 0; q < p.radii.size(); ++q) {
    const double a = gamma * p.radii[q], v = sphere(p.radii[q]);
    for (int k = 0; k < 12; ++k)
      for (int j = 0; j < 12; ++j)
        for (int i = 0; i < 12; ++i) {
          double frac = 1;
          const int g[3] = {i, j, k};
          for (int d = 0; d < 3; ++d) {
            const double lo = std::max(g[d] * 0.5, p.centres[3 * q + d] - a);
            const double hi = std::min((g[d] + 1) * 0.5, p.centres[3 * q + d] + a);
            frac *= std::max(hi - lo, 0.0) / (2 * a);
          }
          ref[i + 12 * (j + 12 * k)] += v * frac;
        }
  }
  for (std::size_t c = 0; c < f.size(); ++c) ASSERT_NEAR(f[c], ref[c], 1e-14) << c;
  // gamma -> 0: the direct method.
  const auto direct = run(e, p, "method=direct deterministic=1");
  const auto tiny = run(e, p, "method=porous_cube gamma=1e-9 deterministic=1");
  for (std::size_t c = 0; c < f.size(); ++c) EXPECT_NEAR(tiny[c], direct[c], 1e-15) << c;
  EXPECT_EQ(e.last_report().fast_path_particles, 300);
  // gamma = 1 and particles of one cell's diameter: the cube is the cell-sized cloud of
  // the trilinear method.
  Particles one = random_particles(200, 0.6, 5.4, 0.25, 0.25, 34);
  const auto cube = run(e, one, "method=porous_cube gamma=1 deterministic=1");
  const auto cic = run(e, one, "method=trilinear deterministic=1");
  for (std::size_t c = 0; c < cube.size(); ++c) EXPECT_NEAR(cube[c], cic[c], 1e-15) << c;
}

TEST(Methods, BigParticleRuleOnHandMadeCases) {
  Engine e(grid(1.0, 4, 4, 4));
  auto idx = [](int i, int j, int k) { return std::size_t(i + 4 * (j + 4 * k)); };
  // On the node (2, 2, 2) with R = 0.9: the 8 cell centres around it are 0.866 away.
  Particles a;
  a.add(2, 2, 2, 0.9);
  auto f = run(e, a, "method=big_particle");
  for (int k = 1; k <= 2; ++k)
    for (int j = 1; j <= 2; ++j)
      for (int i = 1; i <= 2; ++i) EXPECT_NEAR(f[idx(i, j, k)], sphere(0.9) / 8, 1e-15);
  EXPECT_NEAR(total(f), sphere(0.9), 1e-14);
  // R = 0.8: no centre within; all to its own cell (a node belongs to the cell above it).
  Particles b;
  b.add(2, 2, 2, 0.8);
  f = run(e, b, "method=big_particle");
  EXPECT_DOUBLE_EQ(f[idx(2, 2, 2)], sphere(0.8));
  // On a cell centre with R = 1.05: that cell and its 6 face neighbours, V/7 each.
  Particles c;
  c.add(1.5, 2.5, 1.5, 1.05);
  f = run(e, c, "method=big_particle");
  for (auto cell : {idx(1, 2, 1), idx(0, 2, 1), idx(2, 2, 1), idx(1, 1, 1), idx(1, 3, 1), idx(1, 2, 0), idx(1, 2, 2)})
    EXPECT_NEAR(f[cell], sphere(1.05) / 7, 1e-15);
  EXPECT_NEAR(total(f), sphere(1.05), 1e-14);
  // At the wall: the centre (-0.5, 2.5, 1.5) beyond x = 0 is one of the 7. nearest sends its
  // share to (0, 2, 1); drop loses it.
  Particles d;
  d.add(0.5, 2.5, 1.5, 1.05);
  f = run(e, d, "method=big_particle outside=nearest");
  EXPECT_NEAR(f[idx(0, 2, 1)], 2 * sphere(1.05) / 7, 1e-15);
  EXPECT_NEAR(total(f), sphere(1.05), 1e-14);
  f = run(e, d, "method=big_particle outside=drop");
  EXPECT_NEAR(e.last_report().dropped_volume, sphere(1.05) / 7, 1e-15);
  EXPECT_NEAR(f[idx(0, 2, 1)], sphere(1.05) / 7, 1e-15);
  // A small particle straddling a face: no centre inside, its own cell takes all.
  Particles s;
  s.add(1.95, 1.5, 1.5, 0.2);
  f = run(e, s, "method=big_particle");
  EXPECT_DOUBLE_EQ(f[idx(1, 1, 1)], sphere(0.2));
}

TEST(Methods, TrilinearSharesBetweenTheEightSurroundingCells) {
  Engine e(grid(1.0, 4, 4, 4));
  auto idx = [](int i, int j, int k) { return std::size_t(i + 4 * (j + 4 * k)); };
  Particles a;
  a.add(2.0, 2.0, 2.0, 0.3);  // on a node: the 8 cells around it
  auto f = run(e, a, "method=trilinear");
  for (int k = 1; k <= 2; ++k)
    for (int j = 1; j <= 2; ++j)
      for (int i = 1; i <= 2; ++i) EXPECT_NEAR(f[idx(i, j, k)], sphere(0.3) / 8, 1e-15);
  Particles b;
  b.add(1.5, 2.5, 3.5, 0.3);  // on a cell centre: that cell only
  f = run(e, b, "method=trilinear");
  EXPECT_DOUBLE_EQ(f[idx(1, 2, 3)], sphere(0.3));
  Particles c;
  c.add(0.25, 1.5, 1.5, 0.2);  // half a cell from the wall: 3/4 in cell 0, 1/4 beyond
  f = run(e, c, "method=trilinear outside=drop");
  EXPECT_NEAR(f[idx(0, 1, 1)], 0.75 * sphere(0.2), 1e-15);
  EXPECT_NEAR(e.last_report().dropped_volume, 0.25 * sphere(0.2), 1e-15);
}

TEST(Methods, VoxelTemplateConvergesToExact) {
  Engine e(grid(1.0, 10, 10, 10));
  const Particles p = random_particles(300, 0.6, 9.4, 0.5, 0.5, 35);  // chi = 1
  const auto exact = run(e, p, "method=exact");
  std::vector<double> vc(exact.size(), 1.0);
  double last = 1e300;
  for (int n : {8, 64, 512, 4096}) {
    const auto f = run(e, p, "method=pmm template=voxel particle_grid=" + std::to_string(n));
    const auto m = vfe::compare_fields(f, exact, vc, p.volume());
    EXPECT_LT(m.volume_error, 1e-12);
    EXPECT_LT(m.l1, last) << n;
    last = m.l1;
  }
  EXPECT_LT(last, 0.02);
  EXPECT_EQ(e.option("template"), "voxel");
}

TEST(Methods, OptionsSigmaAndGamma) {
  Engine e(grid(1.0, 2, 2, 2));
  EXPECT_EQ(e.option("sigma"), "0.25");
  EXPECT_NEAR(std::stod(e.option("gamma")), std::cbrt(std::numbers::pi / 6), 1e-15);  // the sphere's volume
  e.configure("sigma=0.125 gamma=3");
  EXPECT_EQ(e.option("sigma"), "0.125");
  EXPECT_EQ(e.option("gamma"), "3");
  EXPECT_NE(e.options().find("sigma=0.125"), std::string::npos);
  for (const char* bad : {"sigma=0", "sigma=-1", "sigma=abc", "gamma=0", "gamma=nan", "gamma=1e9", "method=cic"}) {
    try {
      e.configure(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT) << bad;
      const std::string key = std::string(bad).substr(0, std::string(bad).find('='));
      EXPECT_NE(std::string(err.what()).find("'" + key + "'"), std::string::npos) << err.what();
    }
  }
  EXPECT_EQ(e.option("sigma"), "0.125");  // all or nothing
  for (const char* m : kAllMethods) {
    e.configure(std::string("method=") + m);
    EXPECT_EQ(e.option("method"), m);
  }
}

// Periodic axes: a particle across x = 0 gives the field of the same particle moved three
// cells in, rolled back by three cells; a centre one period away gives the same field.
TEST(Periodic, ParticlesAcrossAPeriodicSideWrapForEveryMethod) {
  vfe::CartesianGridSpec g;
  g.cells = {6, 5, 4};
  vfe::Engine e(g);
  const double r = 0.45, vol = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double across[3] = {0.2, 2.4, 1.7}, inside[3] = {3.2, 2.4, 1.7}, far[3] = {0.2 - 12.0, 2.4, 1.7};
  std::vector<double> fa(e.cell_count()), fi(e.cell_count()), ff(e.cell_count());
  for (const char* m : {"direct", "pmm", "exact", "divided", "gaussian", "porous_cube", "big_particle", "trilinear"}) {
    const std::string base = std::string("method=") + m + " orientation=none deterministic=1";
    e.configure(base + " periodic=xyz");
    e.compute(vfe::ParticleView{1, across, &r}, fa);
    e.compute(vfe::ParticleView{1, far, &r}, ff);
    EXPECT_EQ(e.option("periodic"), "xyz");
    e.configure(base + " periodic=none");
    e.compute(vfe::ParticleView{1, inside, &r}, fi);
    double sum = 0, diff = 0, diff_far = 0;
    for (int k = 0; k < 4; ++k)
      for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 6; ++i) {
          const int c = i + 6 * (j + 5 * k), shifted = (i + 3) % 6 + 6 * (j + 5 * k);
          sum += fa[c];
          diff += std::abs(fa[c] - fi[shifted]);
          diff_far += std::abs(ff[c] - fa[c]);
        }
    EXPECT_NEAR(sum, vol, 1e-14) << m;
    EXPECT_LT(diff, 1e-12) << m;
    EXPECT_LT(diff_far, 1e-12) << m;
    // Some volume really is on the far side (cells i = 5).
    double far_side = 0;
    for (int k = 0; k < 4; ++k)
      for (int j = 0; j < 5; ++j) far_side += fa[5 + 6 * (j + 5 * k)];
    // direct and big_particle (one cell centre within the particle here) keep to cell 0.
    if (std::string(m) != "direct" && std::string(m) != "big_particle") {
      EXPECT_GT(far_side, 0.0) << m;
    }
  }
  EXPECT_THROW(e.configure("periodic=xq"), vfe::Error);
}

// Kernels of the methods users compare against: the divided point set, the voxel template,
// gaussian weights, box overlaps of the porous cube, cloud-in-cell weights, the bigParticle
// rule. Oracles are independent of the kernels: hand computation, brute force, quadrature.
#include <vfe/kernels/big_particle.hpp>
#include <vfe/kernels/divided.hpp>
#include <vfe/kernels/gaussian.hpp>
#include <vfe/kernels/particle_template.hpp>
#include <vfe/kernels/porous_cube.hpp>
#include <vfe/kernels/trilinear.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <vector>

using namespace vfe::kernels;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDeg = std::numbers::pi / 180.0;

double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

}  // namespace

// --- divided -----------------------------------------------------------------------------

TEST(Divided, TwentyNinePointsAsSpecified) {
  const ParticleTemplate t = make_divided_template();
  ASSERT_EQ(t.size(), 29u);
  EXPECT_EQ(t.family, "divided");
  EXPECT_EQ(t.points[0], Eigen::Vector3d::Zero());
  for (double f : t.fractions) EXPECT_DOUBLE_EQ(f, 1.0 / 29.0);
  EXPECT_NEAR(sum(t.fractions), 1.0, 1e-15);
  // The layout from its description: per shell 6 axial directions and 8 at polar angle 45
  // or 135 degrees with azimuth 45 + 90 k degrees.
  std::vector<Eigen::Vector3d> expected;
  for (double shell : {0.623926, 0.917902}) {
    for (int axis = 0; axis < 3; ++axis)
      for (double s : {1.0, -1.0}) {
        Eigen::Vector3d v = Eigen::Vector3d::Zero();
        v[axis] = s * shell;
        expected.push_back(v);
      }
    for (double polar : {45.0, 135.0})
      for (int k = 0; k < 4; ++k) {
        const double az = (45.0 + 90.0 * k) * kDeg, th = polar * kDeg;
        expected.push_back(shell * Eigen::Vector3d(std::sin(th) * std::cos(az), std::sin(th) * std::sin(az),
                                                   std::cos(th)));
      }
  }
  ASSERT_EQ(expected.size(), 28u);
  // Every expected point is in the template once (any order), and nothing else is.
  std::vector<bool> used(29, false);
  used[0] = true;
  for (const auto& e : expected) {
    int found = -1;
    for (int i = 1; i < 29; ++i)
      if (!used[i] && (t.points[i] - e).norm() < 1e-12) found = i;
    ASSERT_GE(found, 0) << "missing point " << e.transpose();
    used[found] = true;
  }
  // Centre of volume at the particle's centre.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < t.size(); ++i) mean += t.fractions[i] * t.points[i];
  EXPECT_LT(mean.norm(), 1e-15);
  EXPECT_NEAR(t.reach, 0.917902, 1e-15);
}

// --- voxel template ------------------------------------------------------------------------

TEST(VoxelTemplate, CountsAgreeWithBruteForce) {
  // Hand counts: m = 1 the centre; m = 2 the 8 cubes (centres at distance sqrt(3)/2);
  // m = 3 the centre, 6 face and 12 edge neighbours (corners at 2/sqrt(3) > 1).
  EXPECT_EQ(voxel_count(1), 1);
  EXPECT_EQ(voxel_count(2), 8);
  EXPECT_EQ(voxel_count(3), 19);
  for (int m = 1; m <= 40; ++m) {
    std::int64_t brute = 0;
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j)
        for (int k = 0; k < m; ++k) {
          const double x = (i + 0.5) * 2.0 / m - 1, y = (j + 0.5) * 2.0 / m - 1, z = (k + 0.5) * 2.0 / m - 1;
          brute += x * x + y * y + z * z <= 1.0;
        }
    EXPECT_EQ(voxel_count(m), brute) << "m = " << m;
  }
}

TEST(VoxelTemplate, CubeCentresInsideTheSphereWithEqualShares) {
  for (int n : {1, 8, 19, 27, 100, 135, 500, 2000}) {
    const ParticleTemplate t = make_voxel_template(n);
    EXPECT_EQ(t.family, "voxel");
    const int m = t.lattice;
    ASSERT_GE(m, 1);
    EXPECT_EQ(static_cast<std::int64_t>(t.size()), voxel_count(m));
    // The nearest count among all lattices.
    std::int64_t best = std::numeric_limits<std::int64_t>::max();
    for (int q = 1; q <= 60; ++q) best = std::min(best, std::abs(voxel_count(q) - n));
    EXPECT_EQ(std::abs(static_cast<std::int64_t>(t.size()) - n), best) << "n = " << n;
    EXPECT_NEAR(sum(t.fractions), 1.0, 1e-13);
    for (double f : t.fractions) EXPECT_DOUBLE_EQ(f, t.fractions[0]);
    std::set<std::tuple<long, long, long>> seen;
    for (const auto& p : t.points) {
      EXPECT_LE(p.norm(), 1.0);
      // On the lattice (2i + 1)/m - 1.
      long idx[3];
      for (int d = 0; d < 3; ++d) {
        const double i = ((p[d] + 1.0) * m - 1.0) / 2.0;
        EXPECT_NEAR(i, std::round(i), 1e-9);
        idx[d] = std::lround(i);
      }
      EXPECT_TRUE(seen.insert({idx[0], idx[1], idx[2]}).second);
    }
    // Symmetric lattice: the centre of volume is the centre.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : t.points) mean += p;
    EXPECT_LT(mean.norm() / t.size(), 1e-12);
  }
  // The cubes fill the sphere as they shrink: count * (2/m)^3 -> 4 pi / 3.
  const ParticleTemplate fine = make_voxel_template(100000);
  const double filled = double(fine.size()) * std::pow(2.0 / fine.lattice, 3);
  EXPECT_NEAR(filled, 4.0 / 3.0 * std::numbers::pi, 0.01);
}

// --- gaussian ------------------------------------------------------------------------------

namespace {

/// Mass of the normal density over [lo, hi] by composite Simpson (independent of erf).
double normal_mass(double c, double sigma, double lo, double hi) {
  if (!(hi > lo)) return 0;
  const int n = 2000;
  const double h = (hi - lo) / n;
  double s = 0;
  for (int i = 0; i <= n; ++i) {
    const double x = lo + i * h;
    const double f = std::exp(-0.5 * (x - c) * (x - c) / (sigma * sigma));
    s += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
  }
  return s * h / 3;
}

}  // namespace

TEST(Gaussian, WeightsSumToOneAndMatchQuadrature) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + int(u(rng) * 9);
    // Cells of varying width, the ends sometimes open (cells beyond a mesh).
    std::vector<double> nodes(m + 1);
    nodes[0] = 0;
    for (int i = 1; i <= m; ++i) nodes[i] = nodes[i - 1] + 0.2 + u(rng);
    const double c = nodes[0] + u(rng) * (nodes[m] - nodes[0]);
    const double sigma = 0.02 + 0.5 * u(rng);
    std::vector<double> open = nodes;
    open[0] = -kInf;
    open[m] = kInf;
    std::vector<double> w(m);
    gaussian_axis_weights(c, sigma, open.data(), m, w.data());
    EXPECT_NEAR(sum(w), 1.0, 1e-14);
    // Oracle: Simpson over each cell clipped to the 3 sigma cut, normalised.
    std::vector<double> ref(m);
    for (int i = 0; i < m; ++i) {
      const double lo = std::max(open[i], c - 3 * sigma), hi = std::min(open[i + 1], c + 3 * sigma);
      ref[i] = normal_mass(c, sigma, lo, hi);
    }
    const double total = sum(ref);
    for (int i = 0; i < m; ++i) {
      EXPECT_NEAR(w[i], ref[i] / total, 1e-9) << "trial " << trial << " cell " << i;
      EXPECT_GE(w[i], 0.0);
      if (open[i + 1] <= c - 3 * sigma || open[i] >= c + 3 * sigma) {
        EXPECT_EQ(w[i], 0.0);  // cut
      }
    }
  }
}

TEST(Gaussian, SymmetricAndNarrowLimit) {
  const double nodes[] = {-2, -1, 0, 1, 2};
  double w[4];
  gaussian_axis_weights(0.0, 0.7, nodes, 4, w);
  EXPECT_NEAR(w[0], w[3], 1e-15);
  EXPECT_NEAR(w[1], w[2], 1e-15);
  EXPECT_GT(w[1], w[0]);
  // A kernel far narrower than the cell: all in the cell holding the centre.
  gaussian_axis_weights(0.3, 1e-300, nodes, 4, w);
  EXPECT_EQ(w[2], 1.0);
  EXPECT_EQ(w[0] + w[1] + w[3], 0.0);
}

// --- porous cube ---------------------------------------------------------------------------

TEST(PorousCube, BoxOverlapHandCases) {
  using V = Eigen::Vector3d;
  EXPECT_DOUBLE_EQ(box_box_overlap(V(0, 0, 0), V(1, 2, 3), V(0, 0, 0), V(1, 2, 3)), 6.0);
  EXPECT_EQ(box_box_overlap(V(0, 0, 0), V(1, 1, 1), V(2, 0, 0), V(3, 1, 1)), 0.0);  // apart
  EXPECT_EQ(box_box_overlap(V(0, 0, 0), V(1, 1, 1), V(1, 0, 0), V(2, 1, 1)), 0.0);  // touching
  EXPECT_DOUBLE_EQ(box_box_overlap(V(0, 0, 0), V(4, 4, 4), V(1, 1, 1), V(2, 3, 1.5)), 1.0);  // nested
  // Partial: [0.5, 1] x [0.25, 1] x [0, 0.5] = 0.5 * 0.75 * 0.5.
  EXPECT_DOUBLE_EQ(box_box_overlap(V(0, 0, 0), V(1, 1, 1), V(0.5, 0.25, -1), V(3, 3, 0.5)), 0.1875);
  EXPECT_EQ(box_box_overlap(V(0, 0, 0), V(1, 1, 1), V(0.5, 0.5, 0.5), V(0.5, 1, 1)), 0.0);  // flat
}

TEST(PorousCube, AxisWeightsAreTheBoxOverlapFractions) {
  std::mt19937_64 rng(22);
  std::uniform_real_distribution<double> u(0, 1);
  const double h = 0.7;
  const int m = 6;
  std::vector<double> nodes(m + 1);
  for (int i = 0; i <= m; ++i) nodes[i] = i * h;
  std::vector<double> open = nodes;
  open[0] = -kInf;
  open[m] = kInf;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d c(h + u(rng) * 4 * h, h + u(rng) * 4 * h, h + u(rng) * 4 * h);
    const double half = 0.01 + u(rng) * 1.5;
    double w[3][m];
    for (int d = 0; d < 3; ++d) interval_axis_weights(c[d] - half, c[d] + half, open.data(), m, w[d]);
    double total = 0;
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i) {
          const double f = w[0][i] * w[1][j] * w[2][k];
          total += f;
          // Cells at the open ends reach to infinity; a large finite box stands in for them.
          auto lo = [&](int g) { return g == 0 ? -1e3 : nodes[g]; };
          auto hi = [&](int g) { return g == m - 1 ? 1e3 : nodes[g + 1]; };
          const double ref = box_box_overlap(c.array() - half, c.array() + half, Eigen::Vector3d(lo(i), lo(j), lo(k)),
                                             Eigen::Vector3d(hi(i), hi(j), hi(k))) /
                             std::pow(2 * half, 3);
          ASSERT_NEAR(f, ref, 1e-13) << trial;
        }
    EXPECT_NEAR(total, 1.0, 1e-14);
  }
  // A vanishing cube: everything in the cell holding it, as the direct method.
  double w[m];
  interval_axis_weights(2.3, 2.3, nodes.data(), m, w);
  EXPECT_EQ(w[3], 1.0);
}

// --- trilinear -----------------------------------------------------------------------------

TEST(Trilinear, CloudInCellWeights) {
  // At a cell centre: all to that cell. On a node: half and half. In between: linear.
  auto a = trilinear_axis(2.5);
  EXPECT_EQ(a.first, 2);
  EXPECT_EQ(a.w0, 1.0);
  EXPECT_EQ(a.w1, 0.0);
  a = trilinear_axis(3.0);
  EXPECT_EQ(a.first, 2);
  EXPECT_DOUBLE_EQ(a.w0, 0.5);
  EXPECT_DOUBLE_EQ(a.w1, 0.5);
  a = trilinear_axis(-0.25);  // between the centres -0.5 and 0.5, nearer the first
  EXPECT_EQ(a.first, -1);
  EXPECT_DOUBLE_EQ(a.w0, 0.75);
  EXPECT_DOUBLE_EQ(a.w1, 0.25);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-5, 5);
  for (int i = 0; i < 1000; ++i) {
    const double x = u(rng);
    const auto t = trilinear_axis(x);
    EXPECT_NEAR(t.w0 + t.w1, 1.0, 1e-15);
    // First moment: the weighted cell centres give back the position.
    EXPECT_NEAR(t.w0 * (t.first + 0.5) + t.w1 * (t.first + 1.5), x, 1e-13);
  }
}

// --- big particle --------------------------------------------------------------------------

TEST(BigParticle, HandCases) {
  // Unit cells; centres at 0.5, 1.5, 2.5, 3.5 per axis.
  const double x[] = {0.5, 1.5, 2.5, 3.5};
  std::vector<std::array<int, 3>> cells;
  std::vector<double> shares;
  auto run = [&](Eigen::Vector3d c, double r) {
    cells.clear();
    shares.clear();
    return big_particle_deposit(c, r, 7.0, x, 4, x, 4, x, 4, [&](int i, int j, int k, double v) {
      cells.push_back({i, j, k});
      shares.push_back(v);
    });
  };
  // Centred on a node: the 8 surrounding centres are sqrt(3)/2 = 0.866 away.
  EXPECT_EQ(run({2, 2, 2}, 0.9), 8);
  for (double v : shares) EXPECT_DOUBLE_EQ(v, 7.0 / 8);
  for (auto c : cells)
    for (int d = 0; d < 3; ++d) EXPECT_TRUE(c[d] == 1 || c[d] == 2);
  EXPECT_EQ(run({2, 2, 2}, 0.85), 0);  // none: the caller uses the own cell
  EXPECT_TRUE(cells.empty());
  // On a cell centre: the centre and the 6 face neighbours (1 away); edges are sqrt(2) away.
  EXPECT_EQ(run({1.5, 1.5, 1.5}, 1.05), 7);
  for (double v : shares) EXPECT_DOUBLE_EQ(v, 1.0);
  EXPECT_EQ(run({1.5, 1.5, 1.5}, 1.5), 19);  // + 12 edge neighbours; corners are sqrt(3) away
  // Off-centre: (1.5, 1.5, 1.5) at 0.3, (2.5, 1.5, 1.5) at 0.7, (0.5, ...) at 1.3.
  EXPECT_EQ(run({1.8, 1.5, 1.5}, 0.75), 2);
  EXPECT_EQ(cells[0], (std::array<int, 3>{1, 1, 1}));
  EXPECT_EQ(cells[1], (std::array<int, 3>{2, 1, 1}));
  EXPECT_DOUBLE_EQ(shares[0] + shares[1], 7.0);
}

// Particle templates: volumes, centroids against independent numerical integration, rotations.
#include <vfe/kernels/particle_template.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

using namespace vfe::kernels;

namespace {

double sum_fractions(const ParticleTemplate& t) {
  double s = 0;
  for (double f : t.fractions) s += f;
  return s;
}

Eigen::Vector3d weighted_mean(const ParticleTemplate& t) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < t.size(); ++i) m += t.fractions[i] * t.points[i];
  return m;
}

/// Centroid of the region r in [r0, r1], cos(theta) in [u1, u0], phi in [p0, p1] by a
/// midpoint rule in (r, theta, phi) with the Jacobian r^2 sin(theta): independent of the
/// closed form the template uses.
Eigen::Vector3d numeric_centroid(double r0, double r1, double u0, double u1, double p0, double p1) {
  const int m = 60;
  const double t0 = std::acos(u0), t1 = std::acos(u1);
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  double v = 0;
  for (int a = 0; a < m; ++a) {
    const double r = r0 + (r1 - r0) * (a + 0.5) / m;
    for (int b = 0; b < m; ++b) {
      const double th = t0 + (t1 - t0) * (b + 0.5) / m;
      for (int c = 0; c < m; ++c) {
        const double ph = p0 + (p1 - p0) * (c + 0.5) / m;
        const double w = r * r * std::sin(th);
        s += w * Eigen::Vector3d(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
        v += w;
      }
    }
  }
  return s / v;
}

}  // namespace

TEST(SphericalTemplate, OneSubElementIsTheCentre) {
  const ParticleTemplate t = make_spherical_template(1);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t.points[0], Eigen::Vector3d::Zero());
  EXPECT_EQ(t.fractions[0], 1.0);
}

TEST(SphericalTemplate, SizesVolumesAndCentreOfVolume) {
  for (int n : {2, 5, 8, 20, 27, 64, 100, 135, 500, 1080, 4000}) {
    const ParticleTemplate t = make_spherical_template(n);
    const Eigen::Vector3i l = spherical_layout(n);
    EXPECT_EQ(int(t.size()), l.prod()) << n;
    EXPECT_LE(std::abs(int(t.size()) - n), std::max(1, n / 10)) << "layout too far from " << n;
    EXPECT_NEAR(sum_fractions(t), 1.0, 1e-13) << n;
    EXPECT_LT(weighted_mean(t).norm(), 1e-13) << n;
    for (const auto& p : t.points) EXPECT_LT(p.norm(), 1.0);
  }
}

TEST(SphericalTemplate, CentroidsMatchNumericalIntegration) {
  const ParticleTemplate t = make_spherical_template(60);
  const int S = t.shells, B = t.bands, K = t.sectors;
  ASSERT_EQ(S * B * K, int(t.size()));
  int idx = 0;
  for (int i = 0; i < S; ++i)
    for (int j = 0; j < B; ++j)
      for (int k = 0; k < K; ++k, ++idx) {
        const double two_pi = 2 * std::numbers::pi;
        const Eigen::Vector3d ref = numeric_centroid(std::cbrt(double(i) / S), std::cbrt(double(i + 1) / S),
                                                     1 - 2.0 * j / B, 1 - 2.0 * (j + 1) / B, two_pi * k / K,
                                                     two_pi * (k + 1) / K);
        EXPECT_LT((t.points[idx] - ref).norm(), 2e-4) << "sub-element " << idx;
      }
}

TEST(FibonacciTemplate, AnySizeEqualVolumesCentred) {
  for (int n : {1, 2, 7, 20, 135, 1000}) {
    const ParticleTemplate t = make_fibonacci_template(n);
    ASSERT_EQ(int(t.size()), n);
    EXPECT_NEAR(sum_fractions(t), 1.0, 1e-13);
    EXPECT_LT(weighted_mean(t).norm(), 1e-13);
    // Recentring moves points by |mean| = O(1/n); the outermost stays within that of the surface.
    for (const auto& p : t.points) EXPECT_LT(p.norm(), 1.0 + 1.0 / n);
  }
}

TEST(FibonacciTemplate, SecondMomentApproachesTheBall) {
  // Equal-volume points spread through the ball: mean |x|^2 -> 3/5 as n grows.
  const ParticleTemplate t = make_fibonacci_template(4000);
  double m2 = 0;
  for (std::size_t i = 0; i < t.size(); ++i) m2 += t.fractions[i] * t.points[i].squaredNorm();
  EXPECT_NEAR(m2, 0.6, 0.01);
}

TEST(RandomRotation, ProperOrthogonalDeterministicAndUniform) {
  Eigen::Vector3d mean_axis = Eigen::Vector3d::Zero();
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix3d r = random_rotation(i, 7);
    EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
    mean_axis += r.col(2);
  }
  EXPECT_EQ(random_rotation(5, 7), random_rotation(5, 7));
  EXPECT_NE(random_rotation(5, 7), random_rotation(6, 7));
  EXPECT_NE(random_rotation(5, 7), random_rotation(5, 8));
  // A uniform rotation sends an axis uniformly over the sphere: mean ~ 0 (sd 1/sqrt(3n)).
  EXPECT_LT((mean_axis / n).norm(), 5.0 / std::sqrt(3.0 * n));
}

TEST(RandomRotation, BankedRotationsAreProperDeterministicAndSpread) {
  Eigen::Vector3d mean_axis = Eigen::Vector3d::Zero();
  const int n = 20000;
  int same_as_previous = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix3d& r = banked_random_rotation(i, 3);
    EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    mean_axis += r.col(2);
    if (i > 0 && r == banked_random_rotation(i - 1, 3)) ++same_as_previous;
  }
  EXPECT_EQ(&banked_random_rotation(5, 3), &banked_random_rotation(5, 3));
  EXPECT_NE(banked_random_rotation(5, 3), banked_random_rotation(5, 4));
  EXPECT_LT(same_as_previous, 20);  // ~ n / 4096 expected
  EXPECT_LT((mean_axis / n).norm(), 5.0 / std::sqrt(3.0 * n));
}

TEST(PointTree, NodesHoldTheirPointsAndSplitThemInHalves) {
  using vfe::kernels::PointTree;
  for (const vfe::kernels::ParticleTemplate& t :
       {vfe::kernels::make_fibonacci_template(8000), vfe::kernels::make_spherical_template(343),
        vfe::kernels::make_voxel_template(1000), vfe::kernels::make_fibonacci_template(17)}) {
    const PointTree tree = vfe::kernels::make_point_tree(t.points, t.fractions);
    const std::size_t n = t.size();
    ASSERT_EQ(tree.points.size(), n);
    ASSERT_EQ(tree.fractions.size(), n);
    // The tree's points are the template's, each once, with its own fraction.
    std::vector<std::size_t> found(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto at = std::find(t.points.begin(), t.points.end(), tree.points[i]);
      ASSERT_NE(at, t.points.end());
      const auto k = static_cast<std::size_t>(at - t.points.begin());
      ++found[k];
      EXPECT_EQ(tree.fractions[i], t.fractions[k]);
    }
    EXPECT_EQ(std::count(found.begin(), found.end(), std::size_t(1)), static_cast<std::ptrdiff_t>(n));
    ASSERT_FALSE(tree.nodes.empty());
    EXPECT_EQ(tree.nodes[0].first, 0u);
    EXPECT_EQ(tree.nodes[0].count, n);
    EXPECT_EQ(tree.nodes[0].skip, tree.nodes.size());
    std::size_t leaves = 0, leaf_points = 0;
    for (std::size_t i = 0; i < tree.nodes.size(); ++i) {
      const PointTree::Node& node = tree.nodes[i];
      double sum = 0;
      for (std::uint32_t q = node.first; q < node.first + node.count; ++q) {
        EXPECT_LE((tree.points[q] - node.centre).norm(), node.radius) << i;
        sum += tree.fractions[q];
      }
      EXPECT_NEAR(node.fraction, sum, 1e-15) << i;
      ASSERT_GT(node.skip, i);
      if (node.leaf()) {
        EXPECT_EQ(node.skip, i + 1) << "a leaf has no children";
        ++leaves;
        leaf_points += node.count;
        continue;
      }
      // Two children, each half of the node's points, the second right after the first's subtree.
      const PointTree::Node& a = tree.nodes[i + 1];
      ASSERT_LT(a.skip, node.skip);
      const PointTree::Node& b = tree.nodes[a.skip];
      EXPECT_EQ(a.first, node.first);
      EXPECT_EQ(a.count, node.count / 2);
      EXPECT_EQ(b.first, a.first + a.count);
      EXPECT_EQ(b.count, node.count - a.count);
      EXPECT_EQ(b.skip, node.skip);
    }
    EXPECT_EQ(leaf_points, n) << "the leaves partition the points";
    EXPECT_GE(leaves, (n + PointTree::kLeafPoints - 1) / PointTree::kLeafPoints);
  }
  EXPECT_TRUE(vfe::kernels::make_point_tree({}, {}).empty());
}

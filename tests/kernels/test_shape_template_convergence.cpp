// Shape templates against exact overlaps: with a partition of its own per particle (a
// variant), the mean L1 error falls at least as n^(-1/2) in every orientation, aligned
// included. Prints the convergence table (shape, orientation, variants, n, mean L1).
#include <vfe/kernels/ellipsoid_overlap.hpp>
#include <vfe/kernels/mesh_overlap.hpp>
#include <vfe/kernels/shape.hpp>

#include "cells.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <random>

using namespace vfe::kernels;

namespace {

constexpr int kPositions = 12;
constexpr int kBlock = 6;  // cells per axis around the particle (it reaches 1.3 from its centre)

TriangleMesh cube_mesh(double side) {
  return vfe::test::box_mesh(Eigen::Vector3d::Constant(-side / 2), Eigen::Vector3d::Constant(side / 2));
}

/// Exact volume of the particle (centre, rotation) in the unit cell [lo, lo + 1].
using ExactOverlap = std::function<double(const Eigen::Vector3d& centre, const Eigen::Matrix3d& rotation,
                                          const Eigen::Vector3d& lo, const Eigen::Vector3d& hi)>;

/// Mean over kPositions particles (fixed seed) of the L1 distance between the template's
/// deposits on the unit grid and the exact overlaps, relative to the particle volume.
/// Particle p uses variant p + 1, or variant 0 for all when `single` is set.
double mean_l1(const Shape& shape, int n, bool rotated, bool single, const ExactOverlap& exact) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const ParticleTemplate shared = single ? make_shape_template_variant(shape, n, 0) : ParticleTemplate{};
  double total = 0;
  std::vector<double> deposit(std::size_t(kBlock * kBlock * kBlock));
  for (int p = 0; p < kPositions; ++p) {
    const Eigen::Vector3d centre(u(rng), u(rng), u(rng));
    const Eigen::Matrix3d rotation = rotated ? random_rotation(std::uint64_t(p), 77) : Eigen::Matrix3d::Identity();
    const ParticleTemplate own = single ? ParticleTemplate{} : make_shape_template_variant(shape, n, std::uint32_t(p + 1), 64);
    const ParticleTemplate& t = single ? shared : own;
    EXPECT_GE(int(t.size()), n * 95 / 100);
    std::fill(deposit.begin(), deposit.end(), 0.0);
    const Eigen::Vector3i base = Eigen::Vector3i::Constant(-kBlock / 2 + 1);  // cells -2 .. 3 around [0, 1)^3
    for (std::size_t s = 0; s < t.size(); ++s) {
      const Eigen::Vector3d x = centre + rotation * t.points[s];
      const Eigen::Vector3i c = x.array().floor().cast<int>().matrix() - base;
      if (!((c.array() >= 0).all() && (c.array() < kBlock).all())) {
        ADD_FAILURE() << "template point outside the block";
        return 1e9;
      }
      deposit[std::size_t(c[0] + kBlock * (c[1] + kBlock * c[2]))] += t.fractions[s] * shape.volume();
    }
    double l1 = 0, inside = 0;
    for (int k = 0; k < kBlock; ++k)
      for (int j = 0; j < kBlock; ++j)
        for (int i = 0; i < kBlock; ++i) {
          const Eigen::Vector3d lo = (Eigen::Vector3i(i, j, k) + base).cast<double>();
          const double v = exact(centre, rotation, lo, lo + Eigen::Vector3d::Ones());
          inside += v;
          l1 += std::fabs(deposit[std::size_t(i + kBlock * (j + kBlock * k))] - v);
        }
    EXPECT_NEAR(inside, shape.volume(), 1e-12);  // the block holds the particle
    total += l1 / shape.volume();
  }
  return total / kPositions;
}

}  // namespace

TEST(ShapeTemplateConvergence, VariantsConvergeAtLeastAsInverseSquareRootInEveryOrientation) {
  const TriangleMesh cube = cube_mesh(1.5);
  const Shape cube_shape = Shape::mesh(cube);
  const Shape ellipsoid = Shape::ellipsoid(1.0, 0.6, 0.3);
  const ExactOverlap cube_exact = [&](const Eigen::Vector3d& c, const Eigen::Matrix3d& r, const Eigen::Vector3d& lo,
                                      const Eigen::Vector3d& hi) { return mesh_box_overlap({&cube, c, r}, lo, hi); };
  const ExactOverlap ellipsoid_exact = [&](const Eigen::Vector3d& c, const Eigen::Matrix3d& r, const Eigen::Vector3d& lo,
                                           const Eigen::Vector3d& hi) {
    return ellipsoid_box_overlap({c, ellipsoid.axes(), r}, lo, hi);
  };
  struct Case {
    const char* name;
    const Shape* shape;
    const ExactOverlap* exact;
  };
  const Case cases[] = {{"cube 1.5", &cube_shape, &cube_exact}, {"ellipsoid 1 0.6 0.3", &ellipsoid, &ellipsoid_exact}};
  const int sizes[] = {125, 1000, 8000};
  std::printf("%-20s %-8s %-12s %6s %10s\n", "shape", "grid", "partitions", "n", "mean L1");
  for (const Case& c : cases)
    for (const bool rotated : {false, true})
      for (const bool single : {true, false}) {
        std::map<int, double> l1;
        for (const int n : sizes) {
          l1[n] = mean_l1(*c.shape, n, rotated, single, *c.exact);
          std::printf("%-20s %-8s %-12s %6d %10.5f\n", c.name, rotated ? "rotated" : "aligned",
                      single ? "variant 0" : "own variant", n, l1[n]);
        }
        const double slope = std::log(l1[8000] / l1[125]) / std::log(8000.0 / 125.0);
        std::printf("%-20s %-8s %-12s  slope %.2f\n", c.name, rotated ? "rotated" : "aligned",
                    single ? "variant 0" : "own variant", slope);
        // The claim: with a partition of its own per particle, at least n^(-1/2).
        if (!single) {
          EXPECT_LT(slope, -0.5) << c.name << (rotated ? " rotated" : " aligned");
        }
      }
}

TEST(ShapeTemplateVariants, EqualVolumesExactCentroidDistinctPartitions) {
  const Shape cube = Shape::mesh(cube_mesh(1.5));
  const Shape ellipsoid = Shape::ellipsoid(1.0, 0.6, 0.3);
  const Shape clump = Shape::clump({{0, 0, 0, 0.6}, {0.5, 0.1, 0, 0.5}});
  for (const Shape* s : {&cube, &ellipsoid, &clump}) {
    const ParticleTemplate a = make_shape_template_variant(*s, 200, 1, 100), b = make_shape_template_variant(*s, 200, 2, 100);
    for (const ParticleTemplate* t : {&a, &b}) {
      ASSERT_EQ(t->size(), 200u) << s->description();
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      double sum = 0;
      for (std::size_t i = 0; i < t->size(); ++i) {
        EXPECT_EQ(t->fractions[i], 1.0 / 200);
        EXPECT_TRUE(s->contains(t->points[i])) << s->description();
        sum += t->fractions[i];
        mean += t->fractions[i] * t->points[i];
      }
      EXPECT_NEAR(sum, 1.0, 1e-13);
      EXPECT_LT((mean - s->centroid()).norm(), 1e-13) << s->description();
    }
    EXPECT_GT((a.points[0] - b.points[0]).norm() + (a.points[100] - b.points[100]).norm(), 1e-3) << s->description();
  }
  // Variant 0 is the deterministic template of make_shape_template.
  const ParticleTemplate old = make_shape_template(cube, 64), zero = make_shape_template_variant(cube, 64, 0);
  ASSERT_EQ(old.size(), zero.size());
  for (std::size_t i = 0; i < old.size(); ++i) EXPECT_EQ(old.points[i], zero.points[i]);
}

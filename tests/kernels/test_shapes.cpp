// Shapes: exact volumes against independent integration and closed forms; templates.
#include <vfe/kernels/shape.hpp>

#include "cells.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <numbers>
#include <random>

using namespace vfe::kernels;

namespace {

constexpr double kPi = std::numbers::pi;

TriangleMesh unit_cube() {
  TriangleMesh m;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) m.vertices.emplace_back(i, j, k);
  auto v = [](int i, int j, int k) { return i + 2 * j + 4 * k; };
  auto quad = [&](int a, int b, int c, int d) {  // counter-clockwise seen from outside
    m.triangles.emplace_back(a, b, c);
    m.triangles.emplace_back(a, c, d);
  };
  quad(v(0, 0, 0), v(0, 1, 0), v(1, 1, 0), v(1, 0, 0));  // z = 0, normal -z
  quad(v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1));  // z = 1
  quad(v(0, 0, 0), v(1, 0, 0), v(1, 0, 1), v(0, 0, 1));  // y = 0
  quad(v(0, 1, 0), v(0, 1, 1), v(1, 1, 1), v(1, 1, 0));  // y = 1
  quad(v(0, 0, 0), v(0, 0, 1), v(0, 1, 1), v(0, 1, 0));  // x = 0
  quad(v(1, 0, 0), v(1, 1, 0), v(1, 1, 1), v(1, 0, 1));  // x = 1
  return m;
}

TriangleMesh tetrahedron() { return vfe::test::tetrahedron_mesh(); }

/// Volume of {(x, y): g(x, y) < 1} x [-h(x, y), h(x, y)] by a fine 2-D midpoint rule.
double superquadric_volume_2d(double a, double b, double c, double e1, double e2) {
  const int m = 2000;
  double v = 0;
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      const double x = -a + 2 * a * (i + 0.5) / m, y = -b + 2 * b * (j + 0.5) / m;
      const double g = std::pow(std::pow(std::abs(x / a), 2 / e2) + std::pow(std::abs(y / b), 2 / e2), e2 / e1);
      if (g < 1) v += 2 * c * std::pow(1 - g, e1 / 2);
    }
  return v * (2 * a / m) * (2 * b / m);
}

double lens_volume(double R, double r, double d) {
  // Intersection of two balls of radii R, r at distance d (|R - r| < d < R + r).
  return kPi * std::pow(R + r - d, 2) * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) / (12 * d);
}

}  // namespace

TEST(TriangleMeshShape, CubeAndTetrahedronMassPropertiesAreExact) {
  const MassProperties cube = mesh_mass_properties(unit_cube());
  EXPECT_NEAR(cube.volume, 1.0, 1e-15);
  EXPECT_LT((cube.centroid - Eigen::Vector3d(0.5, 0.5, 0.5)).norm(), 1e-15);
  EXPECT_LT((cube.second_moment - Eigen::Matrix3d::Identity() / 12.0).norm(), 1e-15);
  const MassProperties tet = mesh_mass_properties(tetrahedron());
  EXPECT_NEAR(tet.volume, 1.0 / 6.0, 1e-16);
  EXPECT_LT((tet.centroid - Eigen::Vector3d(0.25, 0.25, 0.25)).norm(), 1e-15);
  // Tetrahedron's integral of x^2 about the origin is 1/60; of x y is 1/120.
  const Eigen::Matrix3d about_origin = tet.second_moment + tet.volume * tet.centroid * tet.centroid.transpose();
  EXPECT_NEAR(about_origin(0, 0), 1.0 / 60, 1e-16);
  EXPECT_NEAR(about_origin(0, 1), 1.0 / 120, 1e-16);
}

TEST(TriangleMeshShape, OpenFlippedAndBadMeshesAreRejected) {
  EXPECT_EQ(check_closed_mesh(unit_cube()), "");
  TriangleMesh open = unit_cube();
  open.triangles.pop_back();
  EXPECT_NE(check_closed_mesh(open).find("open"), std::string::npos) << check_closed_mesh(open);
  TriangleMesh flipped = tetrahedron();
  for (auto& t : flipped.triangles) std::swap(t[1], t[2]);
  EXPECT_NE(check_closed_mesh(flipped).find("inward"), std::string::npos) << check_closed_mesh(flipped);
  TriangleMesh inconsistent = tetrahedron();
  std::swap(inconsistent.triangles[0][1], inconsistent.triangles[0][2]);
  EXPECT_NE(check_closed_mesh(inconsistent), "");
  TriangleMesh bad_index = tetrahedron();
  bad_index.triangles[2][0] = 9;
  EXPECT_NE(check_closed_mesh(bad_index).find("vertex 9"), std::string::npos);
  EXPECT_THROW(Shape::mesh(open), std::invalid_argument);
}

TEST(TriangleMeshShape, ContainsAndTemplate) {
  const Shape cube = Shape::mesh(unit_cube());
  EXPECT_TRUE(cube.contains({0.3, 0.6, 0.9}));
  EXPECT_FALSE(cube.contains({0.3, 0.6, 1.1}));
  EXPECT_FALSE(cube.contains({-0.1, 0.5, 0.5}));
  const ParticleTemplate t = make_shape_template(cube, 64);
  ASSERT_EQ(t.size(), 64u);
  double sum = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d m2 = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < t.size(); ++i) {
    sum += t.fractions[i];
    mean += t.fractions[i] * t.points[i];
    EXPECT_TRUE(cube.contains(t.points[i]));
    EXPECT_NEAR(t.fractions[i], 1.0 / 64, 1e-3);
  }
  for (std::size_t i = 0; i < t.size(); ++i) m2 += t.fractions[i] * (t.points[i] - mean) * (t.points[i] - mean).transpose();
  EXPECT_NEAR(sum, 1.0, 1e-13);
  EXPECT_LT((mean - Eigen::Vector3d(0.5, 0.5, 0.5)).norm(), 1e-13);
  // 4 x 4 x 4 sub-cubes as point masses: second moment 1/12 - 1/(12*16) per axis.
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(m2(d, d), (1.0 - 1.0 / 16) / 12, 2e-3);
}

TEST(EllipsoidShape, VolumeAndTemplate) {
  const Shape e = Shape::ellipsoid(1.0, 0.5, 0.25);
  EXPECT_NEAR(e.volume(), 4.0 / 3.0 * kPi * 0.125, 1e-15);
  const ParticleTemplate t = make_shape_template(e, 100);
  double sum = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < t.size(); ++i) {
    sum += t.fractions[i];
    mean += t.fractions[i] * t.points[i];
    EXPECT_TRUE(e.contains(t.points[i]));
  }
  EXPECT_NEAR(sum, 1.0, 1e-13);
  EXPECT_LT(mean.norm(), 1e-13);
  // Sampled volume (an independent midpoint rule) agrees with 4/3 pi a b c.
  const SampledBody s = sample_shape(e, 400000);
  EXPECT_NEAR(double(s.points.size()) * s.cell_volume, e.volume(), 3e-3 * e.volume());
}

TEST(SuperquadricShape, VolumeMatchesBetaFunctionsAndIntegration) {
  const Shape sphere_like = Shape::superquadric(1, 1, 1, 1, 1);
  EXPECT_NEAR(sphere_like.volume(), 4.0 / 3.0 * kPi, 1e-12);
  for (auto [e1, e2] : {std::pair{0.3, 0.3}, std::pair{0.5, 1.5}, std::pair{1.8, 0.6}, std::pair{0.1, 0.1}}) {
    const Shape q = Shape::superquadric(1.0, 0.7, 0.5, e1, e2);
    EXPECT_NEAR(q.volume(), superquadric_volume_2d(1.0, 0.7, 0.5, e1, e2), 2e-4 * q.volume()) << e1 << " " << e2;
  }
  // e -> 0 tends to the box 8 a b c.
  EXPECT_NEAR(Shape::superquadric(1, 1, 1, 0.1, 0.1).volume(), 8.0, 0.4);
  EXPECT_THROW(Shape::superquadric(1, 1, 1, 0.0, 1), std::invalid_argument);
}

TEST(ClumpShape, UnionVolumeIsExact) {
  // Two overlapping balls: V1 + V2 - lens.
  const double R = 1.0, r = 0.7, d = 1.2;
  const Shape two = Shape::clump({{0, 0, 0, R}, {d, 0, 0, r}});
  const double expect = 4.0 / 3.0 * kPi * (R * R * R + r * r * r) - lens_volume(R, r, d);
  EXPECT_NEAR(two.volume(), expect, 1e-10 * expect);
  // Along z as well (the slicing direction), and a sphere inside another counts once.
  const Shape two_z = Shape::clump({{0, 0, 0, R}, {0, 0, d, r}, {0, 0, 0.1, 0.3}});
  EXPECT_NEAR(two_z.volume(), expect, 1e-10 * expect);
  // Equal balls: centroid at the midpoint.
  const Shape pair = Shape::clump({{0, 0, 0, 0.5}, {0.6, 0.3, 0.2, 0.5}});
  EXPECT_LT((pair.centroid() - Eigen::Vector3d(0.3, 0.15, 0.1)).norm(), 1e-10);
  // Three mutually overlapping balls against a fine sampling (independent).
  const Shape three = Shape::clump({{0, 0, 0, 0.6}, {0.5, 0.1, 0, 0.5}, {0.2, 0.45, 0.3, 0.55}});
  const SampledBody s = sample_shape(three, 2000000);
  EXPECT_NEAR(three.volume(), double(s.points.size()) * s.cell_volume, 2e-3 * three.volume());
}

TEST(DiskUnion, AreasOfDisjointNestedAndOverlappingDisks) {
  EXPECT_NEAR(disk_union({{0, 0, 1}, {3, 0, 1}}).area, 2 * kPi, 1e-14);
  EXPECT_NEAR(disk_union({{0, 0, 1}, {0.2, 0, 0.5}}).area, kPi, 1e-14);
  EXPECT_NEAR(disk_union({{0, 0, 1}, {0, 0, 1}}).area, kPi, 1e-14);
  // Two unit disks at distance 1: lens area 2 acos(1/2) - sqrt(3)/2.
  const double lens = 2 * std::acos(0.5) - std::sqrt(3.0) / 2;
  const DiskUnion u = disk_union({{0, 0, 1}, {1, 0, 1}});
  EXPECT_NEAR(u.area, 2 * kPi - lens, 1e-14);
  EXPECT_NEAR(u.moment_x / u.area, 0.5, 1e-14);
  EXPECT_NEAR(u.moment_y, 0.0, 1e-14);
  // Far from the origin: each group of overlapping disks is integrated about its own centre,
  // so a unit disk 1e90 away keeps its area (about the origin none of it was left).
  EXPECT_NEAR(disk_union({{0, 0, 1}, {1e90, 0, 1}}).area, 2 * kPi, 1e-14);
  const DiskUnion far = disk_union({{1e12, -3e11, 1}, {1e12 + 1, -3e11, 1}});
  EXPECT_NEAR(far.area, 2 * kPi - lens, 1e-13);
  EXPECT_NEAR(far.moment_x / far.area, 1e12 + 0.5, 1e-3);
  EXPECT_NEAR(far.moment_y / far.area, -3e11, 1e-3);
}

// Regression (found by fuzzing): a clump of spheres far apart, whose slices' areas lost
// all their digits to Green's terms about a far origin, drove the adaptive integration to
// its full depth (hours). Now a clump within the limits gets its exact volume, and one
// beyond them is refused at once.
TEST(ClumpShape, SpheresFarApartKeepTheExactVolume) {
  const Shape spread = Shape::clump({{0, 0, 0, 1}, {1, 0, 0, 1}, {1e6, 0, 0, 1}});
  const double expect = 3 * 4.0 / 3.0 * kPi - lens_volume(1, 1, 1);
  EXPECT_NEAR(spread.volume(), expect, 1e-10 * expect);
  EXPECT_THROW((void)Shape::clump({{0, 0, 0, 1}, {1e90, 0, 0, 1}}), std::invalid_argument);
}

// Regression: the volume integration's tolerance was scaled to the volume while the moments
// carry one more length, so a clump of spheres of radius 1e4 (micrometres, say) never met
// it (hours before the slice budget, refused after it). It now integrates in units of the
// largest radius: the same exact volume and centroid, scaled, at every size.
TEST(ClumpShape, VolumeAndCentroidAreExactAtEverySize) {
  const double d = std::sqrt(0.5 * 0.5 + 0.2 * 0.2 + 0.3 * 0.3);
  const double expect = 4.0 / 3.0 * kPi * (1 + 0.8 * 0.8 * 0.8) - lens_volume(1, 0.8, d);
  const Shape unit = Shape::clump({{0, 0, 0, 1}, {0.5, 0.2, 0.3, 0.8}});
  for (const double r : {1e-6, 1.0, 1e4, 1e30}) {
    const Shape s = Shape::clump({{0, 0, 0, r}, {0.5 * r, 0.2 * r, 0.3 * r, 0.8 * r}});
    EXPECT_NEAR(s.volume() / (r * r * r), expect, 1e-10 * expect) << r;
    EXPECT_LT((s.centroid() / r - unit.centroid()).norm(), 1e-12) << r;
  }
  // A tiny sphere inside a huge one counts once.
  const Shape nested = Shape::clump({{0, 0, 0, 1e30}, {0, 0, 0, 1e-30}});
  EXPECT_NEAR(nested.volume() / 1e90, 4.0 / 3.0 * kPi, 1e-12);
}

TEST(ShapeTemplate, ClumpAndSuperquadricTemplatesAreCentredEqualVolumeInside) {
  for (const Shape& s : {Shape::clump({{0, 0, 0, 0.6}, {0.5, 0.1, 0, 0.5}}), Shape::superquadric(1, 0.6, 0.4, 0.4, 0.8)}) {
    const ParticleTemplate t = make_shape_template(s, 50);
    ASSERT_EQ(t.size(), 50u);
    double sum = 0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < t.size(); ++i) {
      sum += t.fractions[i];
      mean += t.fractions[i] * t.points[i];
      EXPECT_NEAR(t.fractions[i], 0.02, 1e-4);
    }
    EXPECT_NEAR(sum, 1.0, 1e-13);
    EXPECT_LT((mean - s.centroid()).norm(), 1e-13);
  }
}

// Sampling walks only the columns the parts cover: spheres far apart (but within the
// limits) are sampled as fully as a compact clump, every sample lies inside, and the
// samples' volume matches the exact one.
TEST(ShapeSampling, SpreadClumpIsSampledWithinItsSpheres) {
  const Shape spread = Shape::clump({{0, 0, 0, 1}, {40, 0, 0, 1}, {0, 40, 3, 0.5}});
  const SampledBody s = sample_shape(spread, 200000);
  ASSERT_GT(s.points.size(), 150000u);
  for (std::size_t i = 0; i < s.points.size(); i += 97) ASSERT_TRUE(spread.contains(s.points[i])) << i;
  EXPECT_NEAR(double(s.points.size()) * s.cell_volume / spread.volume(), 1.0, 0.01);
  EXPECT_LT(check_sampling_cost(spread, 200000), 3 * 200000.0);
}

// A mesh's unused vertices do not stretch its box; shapes too thin or spread for their
// volume are refused when made, with the limit in the message.
TEST(ShapeSampling, StrayVerticesAreIgnoredAndCostlyShapesRefused) {
  TriangleMesh cube = unit_cube();
  cube.vertices.emplace_back(1e12, -1e12, 1e12);
  const Shape s = Shape::mesh(cube);
  EXPECT_EQ(s.bounds().min(), Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(s.bounds().max(), Eigen::Vector3d(1, 1, 1));
  EXPECT_NEAR(s.centroid().x(), 0.5, 1e-12);
  const auto refused = [](const std::function<Shape()>& make) {
    try {
      (void)make();
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("limit"), std::string::npos) << e.what();
    }
  };
  refused([] { return Shape::clump({{0, 0, 0, 1}, {0, 1e9, 0, 1}}); });
  refused([] {
    TriangleMesh sliver = tetrahedron();
    sliver.vertices[3] = Eigen::Vector3d(0, 0, 1e-9);
    return Shape::mesh(sliver);
  });
  refused([] {
    TriangleMesh many;
    many.triangles.resize(kMaxMeshTriangles + 1, Eigen::Vector3i(0, 1, 2));
    return Shape::mesh(many);
  });
}

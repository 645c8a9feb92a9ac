// Ellipsoid and triangle-mesh particles against cells: independent integration, exact
// cases (containment, tilings, symmetric cuts, degenerate contacts), both cell forms.
#include <vfe/kernels/ellipsoid_overlap.hpp>
#include <vfe/kernels/mesh_overlap.hpp>
#include <vfe/kernels/porous_cube.hpp>

#include "cells.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

using namespace vfe::kernels;
using vfe::test::box_cell;
using vfe::test::box_mesh;
using vfe::test::tetrahedron_mesh;
using vfe::test::cell_tetrahedra;
using vfe::test::FacedCell;
using vfe::test::warped_grid;

namespace {

Eigen::Matrix3d turn(double angle, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

/// Volume of the ellipsoid inside [lo, hi] by a midpoint rule over x, y of the exact
/// z-interval of each vertical line (a quadratic): independent of the affine map.
double ellipsoid_box_columns(const Ellipsoid& e, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int m) {
  const Eigen::Matrix3d a = e.to_unit().transpose() * e.to_unit();  // x^T A x <= 1
  double v = 0;
  const double hx = (hi[0] - lo[0]) / m, hy = (hi[1] - lo[1]) / m;
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector3d p = Eigen::Vector3d(lo[0] + (i + 0.5) * hx, lo[1] + (j + 0.5) * hy, 0) - e.centre;
      // (p + t z)^T A (p + t z) = 1: A_zz t^2 + 2 (A p)_z t + p^T A p - 1 = 0.
      const double qa = a(2, 2), qb = (a * p)[2], qc = p.dot(a * p) - 1;
      const double disc = qb * qb - qa * qc;
      if (disc <= 0) continue;
      // p has z = -centre z, so t is the world z.
      const double t1 = (-qb - std::sqrt(disc)) / qa, t2 = (-qb + std::sqrt(disc)) / qa;
      v += std::max(0.0, std::min(t2, hi[2]) - std::max(t1, lo[2]));
    }
  return v * hx * hy;
}

/// The L-shaped prism [0,2]x[0,1]x[0,1] u [0,1]x[1,2]x[0,1] (non-convex).
TriangleMesh l_mesh() {
  TriangleMesh m;
  const double xy[6][2] = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
  for (int z = 0; z < 2; ++z)
    for (const auto& p : xy) m.vertices.emplace_back(p[0], p[1], z);
  // Fans about the reflex corner (1, 1): bottom seen from below, top from above.
  for (int k : {4, 5, 0, 1}) {
    const int next = (k + 1) % 6;
    m.triangles.emplace_back(3, next, k);
    m.triangles.emplace_back(6 + 3, 6 + k, 6 + next);
  }
  for (int k = 0; k < 6; ++k) {
    const int next = (k + 1) % 6;
    m.triangles.emplace_back(k, next, 6 + next);
    m.triangles.emplace_back(k, 6 + next, 6 + k);
  }
  return m;
}

Eigen::Vector3d random_point(std::mt19937& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return {u(rng), u(rng), u(rng)};
}

void sort_box(Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  for (int d = 0; d < 3; ++d)
    if (lo[d] > hi[d]) std::swap(lo[d], hi[d]);
}

}  // namespace

TEST(EllipsoidOverlap, ContainedAndTiledCellsGiveTheVolume) {
  Ellipsoid e{{0.3, -0.2, 0.5}, {1.0, 0.6, 0.3}, turn(0.9, {1, -2, 0.5})};
  const double volume = 4.0 / 3.0 * std::numbers::pi * 0.18;
  EXPECT_NEAR(e.volume(), volume, 1e-15);
  EXPECT_EQ(ellipsoid_box_overlap(e, Eigen::Vector3d::Constant(-2), Eigen::Vector3d::Constant(3)), e.volume());
  EXPECT_EQ(ellipsoid_box_overlap(e, Eigen::Vector3d::Constant(2), Eigen::Vector3d::Constant(3)), 0.0);
  EXPECT_EQ(ellipsoid_box_overlap(e, Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 1)), 0.0);  // empty box
  // A reflection describes the same ellipsoid.
  Ellipsoid mirrored = e;
  mirrored.rotation.col(0) *= -1;
  EXPECT_NEAR(ellipsoid_box_overlap(mirrored, {0, 0, 0}, {1, 1, 1}), ellipsoid_box_overlap(e, {0, 0, 0}, {1, 1, 1}), 1e-15);
  // Boxes of a grid over the ellipsoid's box, and warped hexahedra (faces and tetrahedra
  // forms) tiling it: the overlaps sum to its volume.
  double boxes = 0;
  const int m = 7;
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const Eigen::Vector3d lo = Eigen::Vector3d(-0.8, -1.3, -0.6) + Eigen::Vector3d(i, j, k) * (2.4 / m);
        boxes += ellipsoid_box_overlap(e, lo, lo + Eigen::Vector3d::Constant(2.4 / m));
      }
  EXPECT_NEAR(boxes, volume, 1e-13);
  // The faces form needs planar faces: parallelepipeds of a sheared grid.
  const auto cells = warped_grid(Eigen::Vector3d(-0.8, -1.3, -0.6), Eigen::Vector3d(1.6, 1.1, 1.8), 5, 0.3, 2);
  double faced = 0, tetra = 0;
  std::vector<Eigen::Vector3d> scratch(8);
  const Eigen::Matrix3d shear = (Eigen::Matrix3d() << 1, 0.3, -0.2, 0, 1, 0.25, 0, 0, 1).finished();
  for (const auto& c : cells) {
    tetra += ellipsoid_polyhedron_overlap(e, cell_tetrahedra(c));
  }
  const int ms = 6;
  for (int k = 0; k < ms; ++k)
    for (int j = 0; j < ms; ++j)
      for (int i = 0; i < ms; ++i) {
        const Eigen::Vector3d lo = Eigen::Vector3d(i, j, k) * (5.0 / ms) - Eigen::Vector3d::Constant(2.5);
        FacedCell p = box_cell(lo, lo + Eigen::Vector3d::Constant(5.0 / ms));
        for (auto& v : p.vertices) v = shear * v;
        faced += ellipsoid_polyhedron_overlap(e, p.vertices, p.offsets, p.faces, scratch);
      }
  EXPECT_NEAR(faced, volume, 1e-13);
  EXPECT_NEAR(tetra, volume, 1e-13);
  // Too little scratch is refused (0), not overrun.
  std::vector<Eigen::Vector3d> small(3);
  EXPECT_EQ(ellipsoid_polyhedron_overlap(e, cells[0].vertices, cells[0].offsets, cells[0].faces, small), 0.0);
}

TEST(EllipsoidOverlap, AgreesWithColumnIntegration) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < 12; ++trial) {
    const Ellipsoid e{random_point(rng, -0.3, 0.3), {1.0, 0.6, 0.3}, turn(0.4 * trial, random_point(rng, 0.1, 1))};
    Eigen::Vector3d lo = random_point(rng, -1.1, 0.6), hi = lo + random_point(rng, 0.3, 1.2);
    const double exact = ellipsoid_box_overlap(e, lo, hi);
    const double columns = ellipsoid_box_columns(e, lo, hi, 1200);
    EXPECT_NEAR(exact, columns, 1e-4 * e.volume()) << trial;
    EXPECT_GE(exact, 0);
  }
}

TEST(EllipsoidOverlap, DegenerateContactsAreExact) {
  const Ellipsoid aligned{{0.5, 0.25, -0.1}, {1.0, 0.6, 0.3}, Eigen::Matrix3d::Identity()};
  const double v = aligned.volume();
  // Tangent faces: the ellipsoid's extreme points on the box's faces.
  EXPECT_EQ(ellipsoid_box_overlap(aligned, {1.5, -1, -1}, {3, 1, 1}), 0.0);
  EXPECT_EQ(ellipsoid_box_overlap(aligned, {-0.5, -0.35, -0.4}, {1.5, 0.85, 0.2}), v);
  // Centre on a face, an edge, a vertex of the box: 1/2, 1/4, 1/8 of the volume.
  const Eigen::Vector3d c = aligned.centre, far = Eigen::Vector3d::Constant(5);
  EXPECT_NEAR(ellipsoid_box_overlap(aligned, {c[0], -5, -5}, far), v / 2, 1e-15);
  EXPECT_NEAR(ellipsoid_box_overlap(aligned, {c[0], c[1], -5}, far), v / 4, 1e-15);
  EXPECT_NEAR(ellipsoid_box_overlap(aligned, c, far), v / 8, 1e-15);
  // Turned: the centre at a vertex shared by 8 boxes: they sum to the volume and
  // opposite octants are equal (central symmetry).
  const Ellipsoid turned{c, {1.0, 0.6, 0.3}, turn(1.1, {0.3, 1, -0.7})};
  double sum = 0;
  std::array<double, 8> oct;
  for (int k = 0; k < 8; ++k) {
    Eigen::Vector3d lo = c, hi = c;
    for (int d = 0; d < 3; ++d) (k >> d & 1 ? hi : lo)[d] += (k >> d & 1 ? 2.0 : -2.0);
    oct[k] = ellipsoid_box_overlap(turned, lo, hi);
    sum += oct[k];
  }
  EXPECT_NEAR(sum, v, 1e-14);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(oct[k], oct[7 - k], 1e-15);
  // Centre on the shared edge of the 4 tetrahedra of an octahedron holding the
  // ellipsoid (all 4 negatively oriented, so the signed sum is minus its volume).
  const Eigen::Vector3d x(3, 0, 0), y(0, 3, 0), z(0, 0, 3);
  EXPECT_NEAR(-ellipsoid_tetrahedron_overlap(turned, c + x, c - x, c + y, c + z)
                  -ellipsoid_tetrahedron_overlap(turned, c + x, c - x, c + z, c - y) -
                  ellipsoid_tetrahedron_overlap(turned, c + x, c - x, c - y, c - z) -
                  ellipsoid_tetrahedron_overlap(turned, c + x, c - x, c - z, c + y),
              v, 1e-14);
}

TEST(MeshOverlap, CubeOnAnAlignedGridGivesExactFractions) {
  const TriangleMesh cube = box_mesh(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(0.5));
  std::mt19937 rng(4);
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::Vector3d centre = random_point(rng, 0.0, 1.0);
    const PlacedMesh placed{&cube, centre, Eigen::Matrix3d::Identity()};
    for (int k = -1; k <= 1; ++k)
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          const Eigen::Vector3d lo(i, j, k), hi = lo + Eigen::Vector3d::Ones();
          const double exact = box_box_overlap(lo, hi, centre - Eigen::Vector3d::Constant(0.5), centre + Eigen::Vector3d::Constant(0.5));
          EXPECT_NEAR(mesh_box_overlap(placed, lo, hi), exact, 1e-15);
        }
  }
  // The tests' classic: the unit cube at (0.3, 0.6, 0.1) in [0, 1]^3 has 0.7 x 0.4 x 0.9.
  const PlacedMesh at{&cube, Eigen::Vector3d(0.8, 1.1, 0.6), Eigen::Matrix3d::Identity()};
  EXPECT_NEAR(mesh_box_overlap(at, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()), 0.7 * 0.4 * 0.9, 1e-15);
}

TEST(MeshOverlap, CubeOnARotatedGridTetrahedronAndLShape) {
  const TriangleMesh cube = box_mesh(Eigen::Vector3d::Constant(-0.75), Eigen::Vector3d::Constant(0.75));
  const PlacedMesh placed{&cube, Eigen::Vector3d(0.37, 0.52, 0.11), turn(0.6, {1, 2, 3})};
  // Tiling cells (boxes, and warped hexahedra in both forms): the sum is the volume.
  double boxes = 0;
  for (int k = -2; k <= 2; ++k)
    for (int j = -2; j <= 2; ++j)
      for (int i = -2; i <= 2; ++i) boxes += mesh_box_overlap(placed, Eigen::Vector3d(i, j, k), Eigen::Vector3d(i + 1, j + 1, k + 1));
  EXPECT_NEAR(boxes, 3.375, 1e-13);
  const auto cells = warped_grid(Eigen::Vector3d::Constant(-1.5), Eigen::Vector3d::Constant(2.5), 4, 0.3, 8);
  double faced = 0, tetra = 0;
  for (const auto& c : cells) {
    faced += mesh_polyhedron_overlap(placed, c.vertices, c.offsets, c.faces);
    tetra += mesh_polyhedron_overlap(placed, cell_tetrahedra(c));
  }
  EXPECT_NEAR(faced, 3.375, 1e-13);
  EXPECT_NEAR(tetra, 3.375, 1e-13);
  // Single cells: a half-space through the centre takes half (central symmetry), a cell
  // holding the cube all of it, and a plane beyond it nothing.
  const Eigen::Vector3d n(0.3, -0.5, 0.8);
  const std::array<Eigen::Vector4d, 1> half{Eigen::Vector4d(n[0], n[1], n[2], n.dot(placed.translation))};
  EXPECT_NEAR(mesh_halfspaces_overlap(placed, half), 3.375 / 2, 1e-14);
  EXPECT_NEAR(mesh_box_overlap(placed, Eigen::Vector3d::Constant(-3), Eigen::Vector3d::Constant(3)), 3.375, 1e-14);
  const std::array<Eigen::Vector4d, 1> beyond{Eigen::Vector4d(1, 0, 0, -2)};
  EXPECT_EQ(mesh_halfspaces_overlap(placed, beyond), 0.0);
  // The tetrahedron against boxes: inclusion-exclusion; scaled by 2 and mirrored.
  const TriangleMesh tet = tetrahedron_mesh();
  std::mt19937 rng(6);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Vector3d lo = random_point(rng, -0.3, 1.2), hi = random_point(rng, -0.3, 1.2);
    sort_box(lo, hi);
    const double exact = vfe::test::simplex_box_volume(lo, hi);
    EXPECT_NEAR(mesh_box_overlap({&tet, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity()}, lo, hi), exact, 1e-15);
    Eigen::Matrix3d mirror = 2 * Eigen::Matrix3d::Identity();
    mirror(0, 0) = -2;  // x -> -2x: the box mirrored and halved maps onto the unit case
    const Eigen::Vector3d mlo(-2 * hi[0], 2 * lo[1], 2 * lo[2]), mhi(-2 * lo[0], 2 * hi[1], 2 * hi[2]);
    EXPECT_NEAR(mesh_box_overlap({&tet, Eigen::Vector3d::Zero(), mirror}, mlo, mhi), 8 * exact, 1e-14);
  }
  // The non-convex L prism: the sum of its two boxes' overlaps, for boxes and turned.
  const TriangleMesh l = l_mesh();
  ASSERT_EQ(check_closed_mesh(l), "");
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Vector3d lo = random_point(rng, -0.3, 2.3), hi = random_point(rng, -0.3, 2.3);
    sort_box(lo, hi);
    const double exact = box_box_overlap(lo, hi, {0, 0, 0}, {2, 1, 1}) + box_box_overlap(lo, hi, {0, 1, 0}, {1, 2, 1});
    EXPECT_NEAR(mesh_box_overlap({&l, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity()}, lo, hi), exact, 1e-15);
  }
  const PlacedMesh turned_l{&l, Eigen::Vector3d(0.2, -0.1, 0.3), turn(2.0, {-1, 0.4, 0.9})};
  double l_sum = 0;
  for (const auto& c : warped_grid(Eigen::Vector3d::Constant(-2.5), Eigen::Vector3d::Constant(2.5), 5, 0.25, 12))
    l_sum += mesh_polyhedron_overlap(turned_l, c.vertices, c.offsets, c.faces);
  EXPECT_NEAR(l_sum, 3.0, 1e-13);
}

TEST(OverlapCost, PerCallTimings) {
  // Not a benchmark: one timing per kernel so the cost can be quoted (printed).
  const auto time_us = [](auto&& f, int reps) {
    const auto t0 = std::chrono::steady_clock::now();
    double sink = 0;
    for (int r = 0; r < reps; ++r) sink += f(r);
    const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / reps;
    EXPECT_TRUE(std::isfinite(sink));
    return us;
  };
  const FacedCell hex = warped_grid(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(), 1, 0.0, 1)[0];
  const std::vector<Eigen::Vector3d> tets = cell_tetrahedra(hex);
  const auto shift = [](int r) { return Eigen::Vector3d(0.5 + 0.001 * (r % 97), 0.4, 0.6); };
  const double box_us = time_us([&](int r) { return box_polyhedron_overlap(shift(r) - Eigen::Vector3d::Constant(0.4), shift(r) + Eigen::Vector3d::Constant(0.4), tets); }, 20000);
  const double tet_us = time_us([&](int r) { return tetrahedron_box_overlap(tets[0], tets[1], tets[2], tets[3] + 0.001 * (r % 7) * Eigen::Vector3d::Ones(), shift(r) - Eigen::Vector3d::Constant(0.3), shift(r)); }, 200000);
  const Ellipsoid e{{0.5, 0.4, 0.6}, {0.5, 0.3, 0.15}, turn(0.7, {1, 2, 3})};
  std::vector<Eigen::Vector3d> scratch(8);
  const double ell_box_us = time_us([&](int r) { return ellipsoid_box_overlap({shift(r), e.semi_axes, e.rotation}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }, 20000);
  const double ell_faces_us = time_us([&](int r) { return ellipsoid_polyhedron_overlap({shift(r), e.semi_axes, e.rotation}, hex.vertices, hex.offsets, hex.faces, scratch); }, 20000);
  const TriangleMesh cube = box_mesh(Eigen::Vector3d::Constant(-0.4), Eigen::Vector3d::Constant(0.4));
  const double mesh_box_us = time_us([&](int r) { return mesh_box_overlap({&cube, shift(r), turn(0.7, {1, 2, 3})}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }, 20000);
  const double mesh_cell_us = time_us([&](int r) { return mesh_polyhedron_overlap({&cube, shift(r), turn(0.7, {1, 2, 3})}, tets); }, 2000);
  std::printf("per call (us): tetrahedron_box_overlap %.3f; box_polyhedron_overlap (24 tets) %.2f; ellipsoid_box_overlap %.2f;"
              " ellipsoid_polyhedron_overlap (hex faces) %.2f; mesh_box_overlap (12 triangles) %.2f;"
              " mesh_polyhedron_overlap (12 triangles x 24 cell tets) %.2f\n",
              tet_us, box_us, ell_box_us, ell_faces_us, mesh_box_us, mesh_cell_us);
}

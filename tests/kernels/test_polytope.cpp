// Convex polytope clipping, tetrahedron quadrature, box and Gaussian integrals over
// polyhedral cells: against closed forms, inclusion-exclusion and tilings.
#include <vfe/kernels/gaussian.hpp>
#include <vfe/kernels/gaussian_polyhedron.hpp>
#include <vfe/kernels/polytope.hpp>
#include <vfe/kernels/porous_cube.hpp>

#include "cells.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

using namespace vfe::kernels;
using vfe::test::box_cell;
using vfe::test::cell_tetrahedra;
using vfe::test::FacedCell;
using vfe::test::simplex_box_volume;
using vfe::test::warped_grid;

namespace {

const Eigen::Vector3d kO(0, 0, 0), kX(1, 0, 0), kY(0, 1, 0), kZ(0, 0, 1);

double factorial(int n) { return std::tgamma(n + 1.0); }

/// The unit cube as 6 tetrahedra around its diagonal (Kuhn), all positive.
std::vector<std::array<Eigen::Vector3d, 4>> kuhn_cube(const Eigen::Vector3d& lo, double side) {
  std::vector<std::array<Eigen::Vector3d, 4>> tets;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms) {
    Eigen::Vector3d a = lo, b = a + side * Eigen::Vector3d::Unit(p[0]), c = b + side * Eigen::Vector3d::Unit(p[1]),
                    d = c + side * Eigen::Vector3d::Unit(p[2]);
    if ((b - a).dot((c - a).cross(d - a)) < 0) std::swap(c, d);
    tets.push_back({a, b, c, d});
  }
  return tets;
}

}  // namespace

TEST(TetrahedronRule, IntegratesMonomialsOfItsDegreeExactly) {
  for (int degree : {1, 2, 5}) {
    const TetrahedronRule& rule = tetrahedron_rule(degree);
    EXPECT_EQ(rule.degree, degree);
    double wsum = 0;
    for (int q = 0; q < rule.size; ++q) {
      wsum += rule.weights[q];
      EXPECT_GT(rule.weights[q], 0);
    }
    EXPECT_NEAR(wsum, 1.0, 1e-15);
    for (int a = 0; a <= degree; ++a)
      for (int b = 0; a + b <= degree; ++b)
        for (int c = 0; a + b + c <= degree; ++c) {
          const auto f = [&](const Eigen::Vector3d& x) { return std::pow(x[0], a) * std::pow(x[1], b) * std::pow(x[2], c); };
          const double exact = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3);
          EXPECT_NEAR(integrate_tetrahedron(f, kO, kX, kY, kZ, rule), exact, 1e-15) << degree << ": " << a << b << c;
        }
  }
  // Degree 5 is not exact at degree 6 (the stated degree is the true one).
  const auto x6 = [](const Eigen::Vector3d& x) { return std::pow(x[0], 6); };
  EXPECT_GT(std::fabs(integrate_tetrahedron(x6, kO, kX, kY, kZ, tetrahedron_rule(5)) - 720.0 / factorial(9)), 1e-7);
}

TEST(ConvexPolytope, TetrahedronAndBoxVolumesAndCentroids) {
  for (const bool flip : {false, true}) {
    const ConvexPolytope t = flip ? ConvexPolytope::tetrahedron(kO, kX, kZ, kY) : ConvexPolytope::tetrahedron(kO, kX, kY, kZ);
    const VolumeMoments m = t.moments();
    EXPECT_NEAR(m.volume, 1.0 / 6, 1e-16);
    EXPECT_LT((m.centroid() - Eigen::Vector3d::Constant(0.25)).norm(), 1e-15);
  }
  const ConvexPolytope b = ConvexPolytope::box({1, 2, 3}, {2, 4, 7});
  EXPECT_NEAR(b.volume(), 8.0, 1e-14);
  EXPECT_LT((b.moments().centroid() - Eigen::Vector3d(1.5, 3, 5)).norm(), 1e-14);
  EXPECT_TRUE(ConvexPolytope::box({0, 0, 0}, {1, 0, 1}).empty());
  EXPECT_TRUE(ConvexPolytope::tetrahedron(kO, kX, kY, kX + kY).empty());
}

TEST(ConvexPolytope, PlaneClipsOfTheCube) {
  // x + y + z <= 1 leaves the corner tetrahedron; <= 1.5 half the cube (symmetry).
  ConvexPolytope corner = ConvexPolytope::box(kO, Eigen::Vector3d::Ones());
  ASSERT_TRUE(corner.clip(Eigen::Vector3d::Ones(), 1.0));
  EXPECT_NEAR(corner.volume(), 1.0 / 6, 1e-15);
  EXPECT_LT((corner.moments().centroid() - Eigen::Vector3d::Constant(0.25)).norm(), 1e-15);
  ConvexPolytope half = ConvexPolytope::box(kO, Eigen::Vector3d::Ones());
  half.clip(2.0 * Eigen::Vector3d::Ones(), 3.0);  // the normal need not be unit
  EXPECT_NEAR(half.volume(), 0.5, 1e-15);
  EXPECT_EQ(half.size(), 10);  // 4 kept corners + a hexagon
  // The other half's first moments add up to the cube's.
  ConvexPolytope other = ConvexPolytope::box(kO, Eigen::Vector3d::Ones());
  other.clip(-Eigen::Vector3d::Ones(), -1.5);
  EXPECT_LT((half.moments().first + other.moments().first - Eigen::Vector3d::Constant(0.5)).norm(), 1e-15);
  // Planes through a vertex, an edge and a face leave the polytope alike.
  ConvexPolytope touch = ConvexPolytope::box(kO, Eigen::Vector3d::Ones());
  touch.clip(Eigen::Vector3d::Ones(), 3.0);
  touch.clip(kX + kY, 2.0);
  touch.clip(kZ, 1.0);
  EXPECT_NEAR(touch.volume(), 1.0, 1e-15);
  touch.clip(-kZ, -1.0);  // keeps the top face only: flat
  EXPECT_NEAR(touch.volume(), 0.0, 1e-15);
  ConvexPolytope gone = ConvexPolytope::box(kO, Eigen::Vector3d::Ones());
  gone.clip(kX, -0.5);
  EXPECT_TRUE(gone.empty());
  EXPECT_EQ(gone.volume(), 0.0);
  // Integrating 1 and x over a clipped polytope gives its moments.
  const auto one = [](const Eigen::Vector3d&) { return 1.0; };
  const auto x = [](const Eigen::Vector3d& p) { return p[0]; };
  EXPECT_NEAR(half.integrate(one, tetrahedron_rule(1)), 0.5, 1e-15);
  EXPECT_NEAR(half.integrate(x, tetrahedron_rule(1)), half.moments().first[0], 1e-15);
}

TEST(ConvexPolytope, ManyPlanesApproachABallAndOverflowIsReported) {
  // 40 tangent planes of the unit ball about a box: volume between ball and box.
  ConvexPolytope p = ConvexPolytope::box(-Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones());
  const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
  for (int k = 0; k < 40; ++k) {
    const double z = 1 - (k + 0.5) / 20, r = std::sqrt(1 - z * z);
    ASSERT_TRUE(p.clip(Eigen::Vector3d(r * std::cos(golden * k), r * std::sin(golden * k), z), 1.0));
  }
  EXPECT_FALSE(p.overflowed());
  EXPECT_GT(p.volume(), 4.0 / 3 * std::numbers::pi);
  EXPECT_LT(p.volume(), 8.0);
  ConvexPolytope q = ConvexPolytope::box(-Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones());
  bool ok = true;
  for (int k = 0; k < 400 && ok; ++k) {
    const double z = 1 - (k + 0.5) / 200, r = std::sqrt(1 - z * z);
    ok = q.clip(Eigen::Vector3d(r * std::cos(golden * k), r * std::sin(golden * k), z), 1.0);
  }
  EXPECT_FALSE(ok);
  EXPECT_TRUE(q.overflowed());
  EXPECT_TRUE(q.empty());
}

TEST(TetrahedronBoxOverlap, MatchesInclusionExclusionAndIsSigned) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 1.2);
  for (int trial = 0; trial < 2000; ++trial) {
    Eigen::Vector3d lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d]) std::swap(lo[d], hi[d]);
    const double exact = simplex_box_volume(lo, hi);
    EXPECT_NEAR(tetrahedron_box_overlap(kO, kX, kY, kZ, lo, hi), exact, 2e-16) << trial;
    EXPECT_NEAR(tetrahedron_box_overlap(kO, kY, kX, kZ, lo, hi), -exact, 2e-16) << trial;
    // The same box as 6 half-spaces.
    const std::array<Eigen::Vector4d, 6> planes{Eigen::Vector4d(1, 0, 0, hi[0]),  Eigen::Vector4d(-1, 0, 0, -lo[0]),
                                                Eigen::Vector4d(0, 1, 0, hi[1]),  Eigen::Vector4d(0, -1, 0, -lo[1]),
                                                Eigen::Vector4d(0, 0, 1, hi[2]),  Eigen::Vector4d(0, 0, -1, -lo[2])};
    EXPECT_NEAR(tetrahedron_halfspaces_overlap(kO, kX, kY, kZ, planes), exact, 2e-16) << trial;
  }
  // Faces, edges and vertices of the box on the tetrahedron's: exact values.
  EXPECT_NEAR(tetrahedron_box_overlap(kO, kX, kY, kZ, kO, Eigen::Vector3d::Ones()), 1.0 / 6, 1e-17);
  EXPECT_EQ(tetrahedron_box_overlap(kO, kX, kY, kZ, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 1, 1)), 0.0);
  EXPECT_EQ(tetrahedron_box_overlap(kO, kX, kY, kZ, -Eigen::Vector3d::Ones(), kO), 0.0);
  EXPECT_NEAR(tetrahedron_box_overlap(kO, kX, kY, kZ, Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d(1, 1, 1)),
              1.0 / 48, 1e-17);
}

TEST(TetrahedronBoxOverlap, RandomTetrahedraOfACubeSumToTheBoxInsideIt) {
  // Kuhn's 6 tetrahedra of a cube, affinely moved: the cube's image is a
  // parallelepiped, but a tiling of a cube by tetrahedra needs no map: use the cube.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.5, 2.0);
  const auto tets = kuhn_cube(Eigen::Vector3d(0.1, -0.2, 0.3), 1.3);
  for (int trial = 0; trial < 500; ++trial) {
    Eigen::Vector3d lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d]) std::swap(lo[d], hi[d]);
    double sum = 0;
    for (const auto& t : tets) sum += tetrahedron_box_overlap(t[0], t[1], t[2], t[3], lo, hi);
    const double exact = box_box_overlap(lo, hi, Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(1.4, 1.1, 1.6));
    EXPECT_NEAR(sum, exact, 1e-15) << trial;
  }
}

TEST(BoxPolyhedronOverlap, BoxCellsAreExactAndWarpedCellsAreAdditive) {
  // Box cells: equal to the box-box overlap.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 3.5);
  const FacedCell cell = box_cell({0.2, 0.1, 0.0}, {1.7, 1.1, 2.5});
  const std::vector<Eigen::Vector3d> tets = cell_tetrahedra(cell);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Vector3d lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d]) std::swap(lo[d], hi[d]);
    const double exact = box_box_overlap(lo, hi, {0.2, 0.1, 0.0}, {1.7, 1.1, 2.5});
    EXPECT_NEAR(box_polyhedron_overlap(lo, hi, cell.vertices, cell.offsets, cell.faces), exact, 1e-15);
    EXPECT_NEAR(box_polyhedron_overlap(lo, hi, tets), exact, 1e-15);
  }
  // Warped hexahedra tiling [0, 3]^3 (non-planar faces): their overlaps with any box sum
  // to the box's volume inside [0, 3]^3.
  const auto cells = warped_grid(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(3.0), 3, 0.3, 5);
  double total = 0;
  for (const auto& c : cells) total += box_polyhedron_overlap(-Eigen::Vector3d::Ones(), Eigen::Vector3d::Constant(4), c.vertices, c.offsets, c.faces);
  EXPECT_NEAR(total, 27.0, 1e-13);
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::Vector3d lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d]) std::swap(lo[d], hi[d]);
    double sum = 0;
    for (const auto& c : cells) sum += box_polyhedron_overlap(lo, hi, c.vertices, c.offsets, c.faces);
    EXPECT_NEAR(sum, box_box_overlap(lo, hi, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(3.0)), 1e-14) << trial;
  }
}

TEST(GaussianPolyhedronIntegral, BoxCellsMatchTheSeparableClosedForm) {
  // Cells of a grid around the kernel: each cell's share equals the product of the
  // per-axis weights of gaussian_axis_weights, within the stated tolerance.
  const Eigen::Vector3d centre(0.37, -0.21, 0.55);
  for (const double sigma : {0.25, 0.6}) {
    const int m = 6;
    const double h = 0.5;
    double nodes[3][m + 1], w[3][m];
    for (int d = 0; d < 3; ++d) {
      for (int i = 0; i <= m; ++i) nodes[d][i] = -1.5 + i * h;
      // The raw (unrenormalised) masses: the end cells reach to infinity.
      nodes[d][0] = -1e3;
      nodes[d][m] = 1e3;
      gaussian_axis_weights(centre[d], sigma, nodes[d], m, w[d]);
    }
    double worst = 0, total = 0;
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i) {
          const auto node = [&](int d, int q) { return std::clamp(nodes[d][q], -1.5, 1.5) * (q == 0 || q == m ? 2 : 1); };
          const FacedCell c = box_cell({node(0, i), node(1, j), node(2, k)}, {node(0, i + 1), node(1, j + 1), node(2, k + 1)});
          const double g = gaussian_polyhedron_integral(centre, sigma, c.vertices, c.offsets, c.faces);
          worst = std::max(worst, std::fabs(g - w[0][i] * w[1][j] * w[2][k]));
          total += g;
        }
    EXPECT_LT(worst, kGaussianCellTolerance) << sigma;
    std::printf("gaussian_polyhedron_integral on box cells, sigma %.2f: largest error %.2e\n", sigma, worst);
    // The grid covers the cut box for sigma = 0.25 (3 sigma = 0.75 around the centre).
    if (sigma == 0.25) {
      EXPECT_NEAR(total, 1.0, m * m * m * kGaussianCellTolerance);
    }
  }
  // A cell holding the whole cut box gets 1; a cell beyond 3 sigma gets exactly 0.
  const FacedCell big = box_cell(-Eigen::Vector3d::Constant(5), Eigen::Vector3d::Constant(5));
  EXPECT_NEAR(gaussian_polyhedron_integral(centre, 0.5, big.vertices, big.offsets, big.faces), 1.0, kGaussianCellTolerance);
  const FacedCell far = box_cell(Eigen::Vector3d(1.87, 0, 0), Eigen::Vector3d(3, 1, 1));
  EXPECT_EQ(gaussian_polyhedron_integral(centre, 0.5, far.vertices, far.offsets, far.faces), 0.0);
}

TEST(GaussianPolyhedronIntegral, WarpedCellsTilingTheCutBoxSumToOne) {
  // Warped hexahedra tiling the cut box (non-planar faces, the signed tetrahedra of the
  // faces): the shares sum to 1 within the tolerance per cell.
  const Eigen::Vector3d centre(0.1, 0.2, -0.3);
  const double sigma = 0.4;
  const auto cells = warped_grid(centre - Eigen::Vector3d::Constant(3 * sigma), centre + Eigen::Vector3d::Constant(3 * sigma), 4, 0.3, 9);
  double total = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (const auto& c : cells) total += gaussian_polyhedron_integral(centre, sigma, c.vertices, c.offsets, c.faces);
  const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / double(cells.size());
  EXPECT_NEAR(total, 1.0, double(cells.size()) * kGaussianCellTolerance);
  // A rotated cube cell: the tetrahedra form and the faces form agree, and the result
  // matches a 10x tighter tolerance to the stated one.
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::array<Eigen::Vector3d, 8> corners;
  for (int k = 0; k < 8; ++k) corners[k] = centre + r * Eigen::Vector3d((k & 1) - 0.2, ((k >> 1) & 1) - 0.5, ((k >> 2) & 1) - 0.4) * 0.8;
  const FacedCell rotated = vfe::test::hex_cell(corners);
  const double coarse = gaussian_polyhedron_integral(centre, sigma, rotated.vertices, rotated.offsets, rotated.faces);
  const double tight = gaussian_polyhedron_integral(centre, sigma, cell_tetrahedra(rotated), kGaussianCellTolerance / 100);
  EXPECT_NEAR(coarse, tight, kGaussianCellTolerance);
  std::printf("gaussian_polyhedron_integral: %.1f us per warped hexahedral cell (%zu cells of side 1.5 sigma)\n", us,
              cells.size());
}

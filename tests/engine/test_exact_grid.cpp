// method=exact on Cartesian grids: the octant path (spheres spanning at most 2 cells per
// axis), its fused pass and the general loop, against per-cell box overlaps (brute force
// over every cell, no window), with the outside policies, periodic axes, degenerate
// placements and volume conservation.
#include <vfe/engine.hpp>

#include "particles.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using vfe::Engine;
using vfe::test::grid;
using vfe::test::Particles;
using vfe::test::run;
using vfe::test::total;

namespace {

/// Brute force: sphere_box_overlap of every sphere with every cell of an n^3 grid of cells
/// h from the origin, and with the images of the sphere shifted by the grid's length along
/// the periodic axes (bit d of periodic for axis d).
std::vector<double> brute_force(const Particles& p, double h, int n, unsigned periodic = 0) {
  std::vector<double> ref(static_cast<std::size_t>(n) * n * n, 0.0);
  const double L = h * n;
  for (std::size_t q = 0; q < p.radii.size(); ++q) {
    Eigen::Vector3d c(p.centres[3 * q], p.centres[3 * q + 1], p.centres[3 * q + 2]);
    for (int d = 0; d < 3; ++d)
      if ((periodic >> d) & 1u) c[d] -= L * std::floor(c[d] / L);  // the engine wraps centres
    for (int sz = -1; sz <= 1; ++sz)
      for (int sy = -1; sy <= 1; ++sy)
        for (int sx = -1; sx <= 1; ++sx) {
          const int s[3] = {sx, sy, sz};
          bool image = true;
          for (int d = 0; d < 3; ++d) image = image && (s[d] == 0 || ((periodic >> d) & 1u));
          if (!image) continue;
          const Eigen::Vector3d shifted = c + L * Eigen::Vector3d(sx, sy, sz);
          for (int k = 0; k < n; ++k)
            for (int j = 0; j < n; ++j)
              for (int i = 0; i < n; ++i)
                ref[static_cast<std::size_t>(i + n * (j + n * k))] += vfe::kernels::sphere_box_overlap(
                    shifted, p.radii[q], Eigen::Vector3d(i * h, j * h, k * h),
                    Eigen::Vector3d((i + 1) * h, (j + 1) * h, (k + 1) * h));
        }
  }
  return ref;
}

void expect_fields_near(const std::vector<double>& f, const std::vector<double>& ref, double tol,
                        const std::string& what) {
  ASSERT_EQ(f.size(), ref.size());
  double worst = 0;
  for (std::size_t c = 0; c < f.size(); ++c) worst = std::max(worst, std::abs(f[c] - ref[c]));
  EXPECT_LE(worst, tol) << what;
}

/// Spheres of radius chi_r * h at random centres inside [margin, L - margin]^3.
Particles random_spheres(int count, double L, double r_lo, double r_hi, double margin, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Particles p;
  for (int i = 0; i < count; ++i) {
    const double r = r_lo + (r_hi - r_lo) * u01(rng);
    p.add(margin + (L - 2 * margin) * u01(rng), margin + (L - 2 * margin) * u01(rng),
          margin + (L - 2 * margin) * u01(rng), r);
  }
  return p;
}

}  // namespace

TEST(ExactGrid, OctantPathMatchesPerCellOverlaps) {
  // Radii from 1e-3 of a cell to a half cell (diameter up to one cell: windows of at most
  // 2 cells per axis), and up to 1.2 cells (the general patch path for wide windows).
  const double h = 0.5;
  const int n = 6;
  for (const double r_hi : {0.25, 0.5, 1.2}) {
    const Particles p = random_spheres(60, h * n, 5e-4, r_hi * h, r_hi * h, 7);
    Engine e(grid(h, n, n, n));
    const auto f = run(e, p, "method=exact");
    expect_fields_near(f, brute_force(p, h, n), 1e-13 * p.volume(), "r_hi " + std::to_string(r_hi));
    EXPECT_NEAR(total(f), p.volume(), 1e-13 * p.volume());
  }
}

TEST(ExactGrid, DegeneratePlacements) {
  // Centres exactly on a node, an edge and a face; a sphere tangent to node planes from
  // inside its window (a plane at +-1 radius); a centre 1e-12 of a cell off a node plane;
  // a tiny sphere on a node; a sphere a cell across whose planes lie within 1e-12 of its
  // surface.
  const double h = 1.0;
  const int n = 4;
  Particles p;
  p.add(2.0, 2.0, 2.0, 0.5);
  p.add(1.0, 2.5, 1.0, 0.5);
  p.add(1.5, 3.0, 2.5, 0.4);
  p.add(2.25, 1.75, 2.5, 0.75);
  p.add(3.0 + 1e-12, 1.5, 0.5, 0.3);
  p.add(1.0, 1.0, 3.0, 1e-6);
  p.add(2.0, 2.0, 1.0, 1.0 - 1e-12);
  Engine e(grid(h, n, n, n));
  const auto f = run(e, p, "method=exact");
  expect_fields_near(f, brute_force(p, h, n), 1e-14 * p.volume(), "degenerate placements");
  EXPECT_NEAR(total(f), p.volume(), 1e-14 * p.volume());
}

TEST(ExactGrid, TangentSpheresLeaveExactZeros) {
  // A sphere touching the six faces of its cell from inside spans two cells per axis
  // (its top reaches the next cell's node plane), whose parts beyond are exactly 0.
  Engine e(grid(1.0, 4, 4, 4));
  Particles p;
  p.add(1.5, 1.5, 2.5, 0.5);
  for (const char* options : {"method=exact", "method=exact accumulation=atomic"}) {
    const auto f = run(e, p, options);
    for (int c = 0; c < 64; ++c) {
      if (c == 1 + 4 * (1 + 4 * 2)) {
        EXPECT_NEAR(f[c], p.volume(), 1e-15 * p.volume()) << options;
      } else {
        EXPECT_EQ(f[c], 0.0) << options << " cell " << c;
      }
    }
    EXPECT_EQ(e.last_report().sub_elements, 8) << options;
  }
}

TEST(ExactGrid, FusedPassEqualsTheGeneralLoop) {
  // The default (one thread, private fields) takes the fused pass; deterministic=1 and
  // accumulation=atomic take the general loop through the driver. Spheres inside the grid
  // and crossing its sides, every outside policy that keeps the volume.
  const double h = 1.0;
  const int n = 5;
  const Particles p = random_spheres(400, h * n, 0.05, 0.75, -0.3, 11);
  Engine e(grid(h, n, n, n));
  for (const char* outside : {"outside=nearest", "outside=centre", "outside=drop"}) {
    // Every run names all the switches: configure keeps what the last one set.
    const std::string base = std::string("method=exact threads=1 ") + outside;
    const auto fused = run(e, p, base + " accumulation=auto deterministic=0 fast_path=1");
    const double dropped = e.last_report().dropped_volume;
    const std::int64_t cells = e.last_report().sub_elements;
    for (const char* loop : {"accumulation=atomic deterministic=0 fast_path=1",
                             "accumulation=auto deterministic=1 fast_path=1",
                             "accumulation=auto deterministic=0 fast_path=0"}) {
      const auto general = run(e, p, base + " " + loop);
      expect_fields_near(fused, general, 1e-15 * p.volume(), base + " " + loop);
      EXPECT_NEAR(e.last_report().dropped_volume, dropped, 1e-15 * p.volume()) << loop;
      if (std::string(loop).find("fast_path=0") == std::string::npos) {
        EXPECT_EQ(e.last_report().sub_elements, cells) << loop;
      }
    }
    EXPECT_NEAR(total(fused) + dropped, p.volume(), 1e-13 * p.volume()) << outside;
  }
}

TEST(ExactGrid, VolumeBeyondTheMeshFollowsThePolicy) {
  // Spheres crossing the grid's sides and corners: the cells get the overlaps, drop loses
  // exactly the rest, error refuses the compute.
  const double h = 1.0;
  const int n = 3;
  Particles p;
  p.add(-0.2, 1.5, 1.5, 0.45);  // a cap beyond x = 0
  p.add(2.9, 2.8, 0.1, 0.35);   // across three sides at a corner
  p.add(1.0, -0.1, 2.0, 0.5);   // on an edge node plane, partly beyond y = 0
  Engine e(grid(h, n, n, n));
  const auto f = run(e, p, "method=exact outside=drop");
  const auto ref = brute_force(p, h, n);
  expect_fields_near(f, ref, 1e-14 * p.volume(), "outside=drop");
  EXPECT_NEAR(e.last_report().dropped_volume, p.volume() - total(ref), 1e-14 * p.volume());
  const auto nearest = run(e, p, "method=exact outside=nearest");
  EXPECT_NEAR(total(nearest), p.volume(), 1e-14 * p.volume());
  e.configure("method=exact outside=error");
  std::vector<double> out(e.cell_count(), 7.0);
  EXPECT_THROW(e.compute(p.view(), out), vfe::Error);
}

TEST(ExactGrid, PeriodicAxesWrapTheParts) {
  // Spheres across the periodic sides go to the cells of the opposite side; on a periodic
  // axis of one cell both parts of a sphere land in that cell.
  const double h = 1.0;
  const int n = 4;
  Particles p;
  p.add(0.1, 2.0, 3.9, 0.4);
  p.add(3.95, 0.02, 1.5, 0.3);
  p.add(2.0, 4.0, 0.0, 0.5);  // centre on the periodic sides' node
  Engine e(grid(h, n, n, n));
  const auto f = run(e, p, "method=exact periodic=xyz");
  expect_fields_near(f, brute_force(p, h, n, 7u), 1e-14 * p.volume(), "periodic=xyz");
  EXPECT_NEAR(total(f), p.volume(), 1e-14 * p.volume());

  // x cells 0 and 1 of the sphere wrap to the one cell; its halves below and above z = 2.
  Engine thin(grid(h, 1, n, n));
  Particles q;
  q.add(0.9, 1.5, 2.0, 0.3);
  for (const char* options : {"method=exact periodic=x", "method=exact periodic=x accumulation=atomic"}) {
    const auto g = run(thin, q, options);
    EXPECT_NEAR(g[1 + n * 1], q.volume() / 2, 1e-15 * q.volume()) << options;
    EXPECT_NEAR(g[1 + n * 2], q.volume() / 2, 1e-15 * q.volume()) << options;
    EXPECT_NEAR(total(g), q.volume(), 1e-15 * q.volume()) << options;
  }
}

TEST(ExactGrid, ChiOneAndTwoConserveVolumeOverManySpheres) {
  // The bench's cases: diameters of one and of half a cell at random centres, each cell
  // at most its volume, the field's sum the spheres' volume.
  for (const double chi : {1.0, 2.0}) {
    const double h = chi;  // diameter 1
    const int n = 8;
    const Particles p = random_spheres(3000, h * n, 0.5, 0.5, 0.5, 13);
    Engine e(grid(h, n, n, n));
    const auto f = run(e, p, "method=exact");
    EXPECT_NEAR(total(f), p.volume(), 1e-13 * p.volume()) << chi;
    for (double v : f) EXPECT_GE(v, 0.0);
    if (chi == 1.0) {
      EXPECT_EQ(e.last_report().sub_elements, 8 * 3000) << "every sphere spans 2 x 2 x 2 cells";
      EXPECT_EQ(e.last_report().fast_path_particles, 0);
    }
  }
}

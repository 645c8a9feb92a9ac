// method=exact for ellipsoids and triangle meshes through the engine, on every mesh kind:
// against analytic volumes (box fractions of an aligned cube, 4/3 pi a b c, tilings that
// must sum to the body), against fine pmm on a polyMesh, the outside policy and refusals.
// The convergence table of docs/shapes.md is DISABLED_ShapeConvergence.Table (run with
// --gtest_also_run_disabled_tests).
#include <vfe/engine.hpp>
#include <vfe/measures.hpp>
#include <vfe/stability.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";
const std::string kCube = "mesh " + kData + "shapes/cube.obj";  // side 1 centred on the origin

vfe::CartesianGridSpec unit_grid(std::int64_t n) {
  vfe::CartesianGridSpec g;
  g.cells = {n, n, n};
  return g;
}

struct Bodies {
  std::vector<double> centres, scales, quats;
  std::vector<std::int32_t> ids;
  void add(std::int32_t id, Eigen::Vector3d c, double scale, Eigen::Quaterniond q = Eigen::Quaterniond::Identity()) {
    ids.push_back(id);
    centres.insert(centres.end(), {c.x(), c.y(), c.z()});
    scales.push_back(scale);
    q.normalize();
    quats.insert(quats.end(), {q.w(), q.x(), q.y(), q.z()});
  }
  vfe::ParticleView view() const {
    vfe::ParticleView v;
    v.n = static_cast<std::int64_t>(ids.size());
    v.centres = centres.data();
    v.radii = scales.data();
    v.orientations = quats.data();
    v.shape_ids = ids.data();
    return v;
  }
};

std::vector<double> run(vfe::Engine& e, const Bodies& b, const std::string& options) {
  e.configure(options);
  std::vector<double> out(static_cast<std::size_t>(e.cell_count()), -1.0);
  e.compute(b.view(), out);
  return out;
}

double sum(const std::vector<double>& f) {
  double s = 0;
  for (double x : f) s += x;
  return s;
}

double overlap_1d(double a0, double a1, double b0, double b1) { return std::max(0.0, std::min(a1, b1) - std::max(a0, b0)); }

Eigen::Quaterniond turned() { return Eigen::Quaterniond(0.9, 0.3, -0.25, 0.2).normalized(); }

vfe::AccuracyMeasures compare(const vfe::Engine& e, const std::vector<double>& f, const std::vector<double>& ref,
                              double volume) {
  std::vector<double> vc(static_cast<std::size_t>(e.cell_count()));
  e.cell_volumes(vc);
  return vfe::compare_fields(f, ref, vc, volume);
}

}  // namespace

TEST(ShapeExact, AlignedCubeGivesTheBoxFractionsOnEveryGrid) {
  const Eigen::Vector3d c(2.3, 2.1, 1.7);
  const double side = 1.5;
  vfe::Engine cart(unit_grid(5));
  std::array<std::vector<double>, 3> nodes;
  for (auto& axis : nodes)
    for (int i = 0; i <= 5; ++i) axis.push_back(i);
  vfe::Engine rect(vfe::RectilinearGridSpec{nodes});
  for (vfe::Engine* e : {&cart, &rect}) {
    Bodies b;
    b.add(e->add_shape(kCube), c, side);
    const auto f = run(*e, b, "method=exact orientation=none");
    for (int k = 0; k < 5; ++k)
      for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 5; ++i) {
          const double expect = overlap_1d(i, i + 1, c.x() - 0.75, c.x() + 0.75) *
                                overlap_1d(j, j + 1, c.y() - 0.75, c.y() + 0.75) *
                                overlap_1d(k, k + 1, c.z() - 0.75, c.z() + 0.75);
          EXPECT_NEAR(f[static_cast<std::size_t>(i + 5 * (j + 5 * k))], expect, 1e-14) << i << j << k;
        }
  }
}

TEST(ShapeExact, TurnedBodiesTileTheCellsAndMatchAcrossGrids) {
  // A rotated cube and a rotated ellipsoid 1 x 0.6 x 0.3 over many cells of a graded grid:
  // the cells' overlaps sum to the body, each cell holds at most its volume, and a uniform
  // rectilinear grid gives the Cartesian field.
  vfe::Engine cart(unit_grid(8));
  std::array<std::vector<double>, 3> uniform, graded;
  for (int d = 0; d < 3; ++d)
    for (int i = 0; i <= 8; ++i) {
      uniform[d].push_back(i);
      graded[d].push_back(8.0 * std::pow(i / 8.0, 1.4));
    }
  vfe::Engine rect(vfe::RectilinearGridSpec{uniform}), grad(vfe::RectilinearGridSpec{graded});
  for (vfe::Engine* e : {&cart, &rect, &grad}) {
    const std::int32_t cube = e->add_shape(kCube), ell = e->add_shape("ellipsoid 1 0.6 0.3");
    Bodies b;
    b.add(cube, {1.6, 1.7, 1.8}, 1.7, turned());  // apart: a cell holds at most its volume
    b.add(ell, {5.2, 5.1, 5.0}, 1.9, Eigen::Quaterniond(0.3, -0.6, 0.5, 0.4));
    const double volume = 1.7 * 1.7 * 1.7 + 4.0 / 3.0 * std::numbers::pi * 0.18 * std::pow(1.9, 3);
    const auto f = run(*e, b, "method=exact orientation=given");
    EXPECT_NEAR(sum(f), volume, 1e-13 * volume);
    std::vector<double> vc(static_cast<std::size_t>(e->cell_count()));
    e->cell_volumes(vc);
    for (std::size_t i = 0; i < f.size(); ++i) EXPECT_LE(f[i], vc[i] * (1 + 1e-12));
    EXPECT_EQ(e->last_report().outside_particles, 0);
    if (e == &rect) {
      cart.configure("method=exact orientation=given");
      std::vector<double> g(static_cast<std::size_t>(cart.cell_count()));
      cart.compute(b.view(), g);
      for (std::size_t i = 0; i < f.size(); ++i) EXPECT_NEAR(f[i], g[i], 1e-13);
    }
  }
}

TEST(ShapeExact, EllipsoidInsideOneCellIsItsVolumeWithAndWithoutTheFastPath) {
  vfe::Engine e(unit_grid(3));
  Bodies b;
  b.add(e.add_shape("ellipsoid 0.4 0.3 0.2"), {1.5, 1.5, 1.5}, 1.1, turned());
  const double v = 4.0 / 3.0 * std::numbers::pi * 0.4 * 0.3 * 0.2 * std::pow(1.1, 3);
  for (const char* fast : {"fast_path=1", "fast_path=0"}) {
    const auto f = run(e, b, std::string("method=exact orientation=given ") + fast);
    EXPECT_NEAR(f[13], v, 1e-15) << fast;
    EXPECT_NEAR(sum(f), v, 1e-15) << fast;
  }
}

TEST(ShapeExact, VolumeBeyondTheMeshFollowsTheOutsidePolicy) {
  // Half of an aligned cube of side 1 sticks out through x = 0.
  vfe::Engine e(unit_grid(3));
  Bodies b;
  b.add(e.add_shape(kCube), {0.0, 1.5, 1.5}, 1.0);
  auto f = run(e, b, "method=exact orientation=none outside=drop");
  EXPECT_NEAR(sum(f), 0.5, 1e-14);
  EXPECT_NEAR(e.last_report().dropped_volume, 0.5, 1e-14);
  EXPECT_EQ(e.last_report().outside_particles, 1);
  f = run(e, b, "method=exact orientation=none outside=nearest");
  EXPECT_NEAR(f[0 + 3 * (1 + 3 * 1)], 1.0, 1e-14);
  EXPECT_THROW(run(e, b, "method=exact orientation=none outside=error"), vfe::Error);
  // Periodic in x: the half beyond x = 0 comes back in the last column.
  f = run(e, b, "method=exact orientation=none periodic=x");
  EXPECT_NEAR(f[0 + 3 * (1 + 3 * 1)], 0.5, 1e-14);
  EXPECT_NEAR(f[2 + 3 * (1 + 3 * 1)], 0.5, 1e-14);
  EXPECT_EQ(e.last_report().outside_particles, 0);
}

TEST(ShapeExact, ShapesWithoutAnExactOverlapAreRefusedNamingTheAlternative) {
  vfe::Engine e(unit_grid(3));
  for (const char* spec : {"clump 0 0 0 0.4; 0.4 0 0 0.3", "superquadric 0.6 0.5 0.4 0.5 0.8"}) {
    Bodies b;
    b.add(e.add_shape(spec), {1.5, 1.5, 1.5}, 1.0);
    e.configure("method=exact");
    std::vector<double> out(27, -1.0);
    try {
      e.compute(b.view(), out);
      FAIL() << spec << " should be refused by exact";
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
      EXPECT_NE(std::string(err.what()).find("method=pmm"), std::string::npos) << err.what();
    }
    EXPECT_EQ(out[0], -1.0);  // nothing written
  }
}

TEST(ShapeExact, PolyMeshMatchesFinePmmAndConservesVolume) {
  // The O-grid cylinder's cells are not boxes: the faces form of both kernels.
  vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"});
  const std::size_t ncell = static_cast<std::size_t>(e.cell_count());
  std::vector<double> centres(3 * ncell), vc(ncell);
  e.cell_centres(centres);
  e.cell_volumes(vc);
  const double h = std::cbrt(*std::max_element(vc.begin(), vc.end()));
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (std::size_t c = 0; c < ncell; ++c) {
    lo = lo.cwiseMin(Eigen::Vector3d(centres[3 * c], centres[3 * c + 1], centres[3 * c + 2]));
    hi = hi.cwiseMax(Eigen::Vector3d(centres[3 * c], centres[3 * c + 1], centres[3 * c + 2]));
  }
  const Eigen::Vector3d mid = 0.5 * (lo + hi);
  Bodies b;
  const std::int32_t cube = e.add_shape(kCube), ell = e.add_shape("ellipsoid 1 0.6 0.3");
  b.add(cube, mid + Eigen::Vector3d(0.3 * h, 0.1 * h, 0), 1.3 * h, turned());
  b.add(ell, mid + Eigen::Vector3d(-0.2 * h, 0.4 * h, 1.5 * h), 1.4 * h, Eigen::Quaterniond(0.3, -0.6, 0.5, 0.4));
  const double volume = std::pow(1.3 * h, 3) + 4.0 / 3.0 * std::numbers::pi * 0.18 * std::pow(1.4 * h, 3);
  const auto exact = run(e, b, "method=exact orientation=given");
  EXPECT_NEAR(sum(exact), volume, 1e-12 * volume);
  EXPECT_EQ(e.last_report().outside_particles, 0);
  std::size_t touched = 0;
  for (std::size_t c = 0; c < ncell; ++c) {
    // vc is OpenFOAM's volume; the overlaps see the cell bounded by its faces (warped ones
    // as fans, the point-location surface), which the warp makes differ by up to ~1e-3.
    EXPECT_LE(exact[c], vc[c] * (1 + 1e-2));
    touched += exact[c] > 0;
  }
  EXPECT_GT(touched, 8u);  // the bodies straddle cells
  const auto pmm = run(e, b, "method=pmm orientation=given particle_grid=4000");
  const vfe::AccuracyMeasures m = compare(e, pmm, exact, volume);
  EXPECT_LT(m.l1, 0.02) << "L1 of pmm 4000 against exact";
  EXPECT_GT(m.l1, 0.0);
}

TEST(ShapeExact, StabilityOfAShapeUsesExactAsItsReference) {
  vfe::StabilityOptions o;
  o.shape = "ellipsoid 1 0.6 0.3";
  o.chi = 1.0;
  o.trajectories = 2;
  o.cells = 0.5;
  o.step = 1.0 / 50;
  o.particle_grids = {"200"};
  const vfe::StabilityReport r = vfe::stability_test(o);
  EXPECT_EQ(r.reference.rfind("method=exact", 0), 0u) << r.reference;
  ASSERT_EQ(r.results.size(), 1u);
  EXPECT_GT(r.results[0].max_jump_exact, 0);
  o.shape = "clump 0 0 0 0.4; 0.4 0 0 0.3";  // no exact overlap: a fine pmm
  o.reference_grid = 400;
  o.trajectories = 1;
  o.particle_grids = {"50"};
  EXPECT_EQ(vfe::stability_test(o).reference.rfind("method=pmm", 0), 0u);
}

// The convergence table of docs/shapes.md: pmm (own variant per particle) against exact,
// through the engine; the clump against pmm with 40000 sub-elements.
TEST(ShapeConvergence, DISABLED_Table) {
  struct Case {
    const char* name;
    std::string spec;
    bool rotated;
  };
  const Case cases[] = {{"cube", kCube, false},
                        {"cube", kCube, true},
                        {"ellipsoid 1 x 0.6 x 0.3", "ellipsoid 1 0.6 0.3", false},
                        {"ellipsoid 1 x 0.6 x 0.3", "ellipsoid 1 0.6 0.3", true},
                        {"clump (2 spheres)", "clump 0 0 0 0.5; 0.5 0 0 0.4", true}};
  std::printf("| shape | orientation | n = 125 | 1000 | 8000 | slope |\n|---|---|---|---|---|---|\n");
  for (const Case& c : cases) {
    vfe::Engine e(unit_grid(8));
    const std::int32_t id = e.add_shape(c.spec);
    const double scale = 1.5 / std::cbrt(e.shape_volume(id));  // volume 1.5^3: chi about 0.8
    Bodies b;
    for (int p = 0; p < 12; ++p) {
      const Eigen::Vector3d at(3.0 + 0.173 * p, 3.5 + 0.091 * p, 4.0 - 0.137 * p);
      b.add(id, at, scale, c.rotated ? Eigen::Quaterniond(0.9 - 0.05 * p, 0.3, -0.25 + 0.04 * p, 0.2) : Eigen::Quaterniond::Identity());
    }
    const double volume = 12 * e.shape_volume(id) * scale * scale * scale;
    const bool exact = c.spec.rfind("clump", 0) != 0;
    const auto ref = run(e, b, exact ? "method=exact orientation=given" : "method=pmm orientation=given particle_grid=40000");
    double l1[3];
    const int ns[3] = {125, 1000, 8000};
    for (int i = 0; i < 3; ++i) {
      const auto start = std::chrono::steady_clock::now();
      const auto f = run(e, b, "method=pmm orientation=given particle_grid=" + std::to_string(ns[i]));
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      l1[i] = compare(e, f, ref, volume).l1;
      std::fprintf(stderr, "%s n=%d first compute (with the template bank) %.3f s\n", c.name, ns[i], t);
    }
    std::printf("| %s%s | %s | %.4f | %.4f | %.4f | %.2f |\n", c.name, exact ? "" : " (vs pmm 40000)",
                c.rotated ? "rotated" : "aligned", l1[0], l1[1], l1[2], std::log(l1[2] / l1[0]) / std::log(64.0));
    EXPECT_LT(l1[2], l1[0]);
  }
}

// Cost per particle of exact against pmm at its stable size (particle_grid=auto) for 2000
// shaped particles, volume-equivalent diameter 1, random positions and orientations, on
// cells of side chi (docs/shapes.md); one thread, median of 5 computes after a first one
// that builds the templates.
TEST(ShapeConvergence, DISABLED_CostPerParticle) {
  std::printf("| shape | chi | method | n | us/particle |\n|---|---|---|---|---|\n");
  for (const char* spec : {"ellipsoid 1 0.6 0.3", "cube"})
    for (const double chi : {1.0, 2.0}) {
      const std::int64_t cells = 16;
      vfe::CartesianGridSpec g;
      g.spacing = {chi, chi, chi};
      g.cells = {cells, cells, cells};
      vfe::Engine e(g);
      const std::int32_t id = e.add_shape(std::string(spec) == "cube" ? kCube : spec);
      const double scale = std::cbrt(std::numbers::pi / 6.0 / e.shape_volume(id));
      Bodies b;
      std::uint64_t state = 7;
      auto u = [&] {  // a fixed-seed uniform in [0, 1)
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return double(state >> 11) * 0x1p-53;
      };
      for (int p = 0; p < 2000; ++p)
        b.add(id, Eigen::Vector3d(1 + u() * (cells * chi - 2), 1 + u() * (cells * chi - 2), 1 + u() * (cells * chi - 2)),
              scale, Eigen::Quaterniond(u() - 0.5, u() - 0.5, u() - 0.5, u() - 0.5));
      for (const char* method : {"method=exact", "method=pmm"}) {
        const std::string options = std::string(method) + " orientation=given threads=1";
        auto f = run(e, b, options);
        std::vector<double> times;
        for (int r = 0; r < 5; ++r) {
          const auto start = std::chrono::steady_clock::now();
          e.compute(b.view(), f);
          times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        }
        std::sort(times.begin(), times.end());
        std::printf("| %s | %.0f | %s | %lld | %.2f |\n", spec, chi, method,
                    static_cast<long long>(e.last_report().particle_grid_max), times[2] / 2000 * 1e6);
        EXPECT_NEAR(sum(f), 2000 * e.shape_volume(id) * scale * scale * scale, 1e-9 * 2000);
      }
    }
}

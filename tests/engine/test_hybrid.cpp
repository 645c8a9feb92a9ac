// method=auto: per sphere the fast path, pmm at particle_grid=auto's size or exact. Each
// sphere's deposits must be those of the path it took, computed alone; the paths are
// counted; shapes take pmm.
#include "particles.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

namespace vfe::test {
namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

/// Solid field of particles [first, first + count) of p, with their ids (the rotation key
/// of orientation=random), so a sphere alone is rotated as in the whole set.
std::vector<double> compute_range(Engine& e, const Particles& p, const std::vector<std::int64_t>& ids,
                                  std::size_t first, std::size_t count) {
  vfe_particles v{};
  v.n = static_cast<std::int64_t>(count);
  v.centres = p.centres.data() + 3 * first;
  v.radii = p.radii.data() + first;
  v.ids = ids.data() + first;
  std::vector<double> out(e.cell_count(), -1.0);
  e.compute(v, out);
  return out;
}

double path_count(const Engine& e, const char* key) { return e.last_report_value(key); }

/// Every sphere of p alone: auto's field equals that of the path auto reports for it (fast
/// and exact against method=exact, pmm against method=pmm) to 1e-14 of its volume, and the
/// whole set under auto is the sum of the spheres alone. Returns the spheres per path.
std::array<int, 3> check_paths(Engine& e, const Particles& p, const std::string& options) {
  std::vector<std::int64_t> ids(p.radii.size());
  std::iota(ids.begin(), ids.end(), 1000);
  std::array<int, 3> paths{0, 0, 0};
  std::vector<double> sum(e.cell_count(), 0.0);
  for (std::size_t i = 0; i < p.radii.size(); ++i) {
    e.configure("method=auto " + options);
    const std::vector<double> hybrid = compute_range(e, p, ids, i, 1);
    const int fast = int(path_count(e, "auto_fast")), pmm = int(path_count(e, "auto_pmm")),
              exact = int(path_count(e, "auto_exact"));
    EXPECT_EQ(fast + pmm + exact, 1);
    const int path = fast ? 0 : (pmm ? 1 : 2);
    ++paths[static_cast<std::size_t>(path)];
    e.configure(std::string(path == 1 ? "method=pmm particle_grid=auto " : "method=exact ") + options);
    const std::vector<double> alone = compute_range(e, p, ids, i, 1);
    const double vp = 4.0 / 3.0 * std::numbers::pi * std::pow(p.radii[i], 3);
    double worst = 0;
    for (std::size_t c = 0; c < alone.size(); ++c) {
      worst = std::max(worst, std::abs(alone[c] - hybrid[c]));
      sum[c] += hybrid[c];
    }
    EXPECT_LE(worst, 1e-14 * vp) << "sphere " << i << " on path " << path;
  }
  ::testing::Test::RecordProperty("paths_fast_pmm_exact",
                 std::to_string(paths[0]) + " " + std::to_string(paths[1]) + " " + std::to_string(paths[2]));
  e.configure("method=auto " + options);
  const std::vector<double> all = compute_range(e, p, ids, 0, p.radii.size());
  EXPECT_EQ(path_count(e, "auto_fast"), paths[0]);
  EXPECT_EQ(path_count(e, "auto_pmm"), paths[1]);
  EXPECT_EQ(path_count(e, "auto_exact"), paths[2]);
  for (std::size_t c = 0; c < all.size(); ++c) EXPECT_NEAR(all[c], sum[c], 1e-13 * p.volume());
  EXPECT_NEAR(std::accumulate(all.begin(), all.end(), 0.0) + e.last_report_value("dropped_volume"), p.volume(),
              1e-12 * p.volume());
  return paths;
}

// Spheres from a quarter of a cell to three cells across: the small ones fit a cell or go
// to pmm's octant count, the large ones to exact (pmm auto would give them 20000 sub-elements).
TEST(Hybrid, CartesianSpheresTakeTheirPathsResult) {
  Engine e(grid(0.001, 12, 12, 12));
  const Particles p = random_spheres(5, 60, 0.0015, 0.0105, 0.00012, 0.0015);
  const auto paths = check_paths(e, p, "outside=nearest");
  EXPECT_GT(paths[0], 0);
  EXPECT_GT(paths[1], 0);
  EXPECT_GT(paths[2], 0);
}

// Equal spheres at chi = 2, whose template (one for all) is cheaper to count than exact on
// any window: the engine runs pmm's quick cases by blocks (the fast path or the count),
// and every sphere is counted as it is alone.
TEST(Hybrid, EqualSpheresTakeTheBlocksOfPmmsQuickCases) {
  Engine e(grid(0.001, 12, 12, 12));
  const Particles p = random_spheres(7, 150, 0.0015, 0.0105, 0.00025, 0.00025);
  const auto paths = check_paths(e, p, "threads=1");
  EXPECT_GT(paths[0], 5);
  EXPECT_GT(paths[1], 100);
  EXPECT_EQ(paths[2], 0);
  EXPECT_GT(e.last_report_value("counted_particles"), 100);
}

// A graded grid (cells 0.4 to 1.6 mm) and the two polyMeshes that are not boxes, where
// exact is the polyhedron overlap: snappy's 0.5 mm cells at the tube send spheres to exact,
// its 2 mm cells to pmm.
TEST(Hybrid, GradedAndPolyhedralSpheresTakeTheirPathsResult) {
  std::array<std::vector<double>, 3> nodes;
  for (auto& x : nodes) {
    x = {0};
    for (double dx = 0.0004; x.back() < 0.012; dx *= 1.15) x.push_back(x.back() + dx);
  }
  Engine graded(RectilinearGridSpec{nodes});
  Particles mixed = random_spheres(6, 40, 0.001, 0.011, 0.00015, 0.0015);
  for (std::size_t k = 8; k <= 10; ++k) {  // small spheres on a face between coarse cells
    const double mid = 0.5 * (nodes[1][k] + nodes[1][k + 1]);
    mixed.add(nodes[0][k], mid, mid, 0.15 * (nodes[0][k + 1] - nodes[0][k]));
  }
  // A graded grid locates pmm's sub-elements by search: exact is cheaper for nearly every sphere.
  const auto g = check_paths(graded, mixed, "outside=drop");
  EXPECT_GT(g[2], 0);
  Engine snappy(PolyMeshSpec{kData + "openfoam/snappy_obstacle"});
  Particles around_tube = random_spheres(7, 40, 0.003, 0.017, 0.0004, 0.0006);
  for (std::size_t i = 2; i < around_tube.centres.size(); i += 3) around_tube.centres[i] += 0.015;  // z 18 to 32 mm
  const auto s = check_paths(snappy, around_tube, "outside=nearest");
  EXPECT_GT(s[1], 0);
  EXPECT_GT(s[2], 0);
  // box_graded computes on its lattice's graded grid; spheres at its walls take each path's
  // own boundary rule (exact: the grid's cells and the rest by the polyMesh's rule; pmm: the
  // polyMesh's driver).
  Engine box(PolyMeshSpec{kData + "openfoam/box_graded"});
  Particles walls = random_spheres(10, 40, 0.0, 0.02, 0.0002, 0.0009);
  walls.add(0.0002, 0.01, 0.01, 0.0003);  // across the wall x = 0
  const auto b = check_paths(box, walls, "outside=nearest");
  EXPECT_GT(b[2], 0);
  Engine cylinder(PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"});
  (void)check_paths(cylinder, random_spheres(8, 30, 0.004, 0.016, 0.0003, 0.0012), "outside=centre");
}

// The engine's modes hold as for the other methods: deterministic=1 gives the same bits on
// 1 and 2 threads, incremental=1 after a move equals a fresh compute, weights=1 gives the
// particles' fractions summing to 1; other methods report no auto path.
TEST(Hybrid, DeterministicIncrementalAndOtherMethodsReport) {
  Engine e(grid(0.001, 12, 12, 12));
  Particles p = random_spheres(9, 400, 0.001, 0.011, 0.00015, 0.0012);
  const std::vector<double> one = run(e, p, "method=auto deterministic=1 threads=1");
  const std::vector<double> two = run(e, p, "method=auto deterministic=1 threads=2");
  EXPECT_EQ(one, two);
  EXPECT_EQ(e.last_report_value("auto_fast") + e.last_report_value("auto_pmm") + e.last_report_value("auto_exact"),
            400.0);
  (void)run(e, p, "method=auto incremental=1 threads=2");
  for (std::size_t i = 0; i < p.radii.size(); i += 7) p.centres[3 * i] += 0.0003;
  std::vector<double> updated(e.cell_count());
  e.compute(p.view(), updated);
  EXPECT_LT(e.last_report_value("auto_pmm") + e.last_report_value("auto_exact") + e.last_report_value("auto_fast"), 100);
  Engine fresh(grid(0.001, 12, 12, 12));
  const std::vector<double> again = run(fresh, p, "method=auto");
  for (std::size_t c = 0; c < again.size(); ++c) EXPECT_NEAR(updated[c], again[c], 1e-13 * p.volume());
  (void)run(fresh, p, "method=auto weights=1");
  const Engine::WeightsSize size = fresh.weights_size();
  std::vector<std::int64_t> offsets(size.particles + 1), cells(size.entries);
  std::vector<double> fractions(size.entries);
  fresh.weights(offsets, cells, fractions);
  for (std::int64_t i = 0; i < size.particles; ++i)
    EXPECT_NEAR(std::accumulate(fractions.begin() + offsets[i], fractions.begin() + offsets[i + 1], 0.0), 1.0, 1e-12);
  (void)run(fresh, p, "method=exact weights=0");
  EXPECT_EQ(fresh.last_report_value("auto_exact"), 0.0);
  EXPECT_EQ(fresh.last_report_value("auto_pmm"), 0.0);
}

// A non-spherical particle keeps pmm: auto's field of ellipsoids is pmm's, and each counts as pmm.
TEST(Hybrid, ShapesTakePmm) {
  Engine e(grid(0.001, 10, 10, 10));
  const std::int32_t id = e.add_shape("ellipsoid 1 0.6 0.4");
  const Particles p = random_spheres(4, 50, 0.002, 0.008, 0.0004, 0.0012);
  std::vector<std::int32_t> ids(p.radii.size(), id);
  ParticleView v = p.view();
  v.shape_ids = ids.data();
  std::vector<double> a(e.cell_count()), b(e.cell_count());
  e.configure("method=auto");
  e.compute(v, a);
  EXPECT_EQ(e.last_report_value("auto_pmm"), 50.0);
  e.configure("method=pmm");
  e.compute(v, b);
  for (std::size_t c = 0; c < a.size(); ++c) EXPECT_NEAR(a[c], b[c], 1e-14 * p.volume());
}

}  // namespace
}  // namespace vfe::test

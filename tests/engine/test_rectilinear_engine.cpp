// Engines on rectilinear (graded Cartesian) grids: the same fields as the Cartesian grid on
// uniform nodes, exact volumes on graded nodes against the Cartesian exact method on a finer
// grid that shares their nodes, periodic axes, and bad nodes.
#include "particles.hpp"
#include "polymesh/rectilinear_grid.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <numbers>
#include <numeric>

#include <algorithm>
#include <cmath>
#include <limits>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <unistd.h>

namespace vfe::test {
namespace {

std::vector<double> uniform_nodes(double lo, double h, int cells) {
  std::vector<double> x(cells + 1);
  for (int i = 0; i <= cells; ++i) x[i] = lo + h * i;
  return x;
}

// axis_index narrows its search to x's bucket: it must give what a binary search over all
// the nodes gives, on nodes, between them, beyond both ends, for strongly graded axes
// (many nodes in one bucket) and for NaN and infinities.
TEST(RectilinearGrid, AxisIndexIsTheBinarySearchOverAllNodes) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    std::array<std::vector<double>, 3> nodes;
    for (int d = 0; d < 3; ++d) {
      const int n = 1 + int(rng() % 40);
      double x = -1 + u(rng);
      nodes[d].push_back(x);
      const double ratio = trial % 2 ? 1.6 : 1.02;  // geometric grading: up to 1.6^40 between cells
      double h = 1e-3 * (1 + u(rng));
      for (int i = 0; i < n; ++i) nodes[d].push_back(x += (h *= ratio));
    }
    const vfe::RectilinearGrid grid(nodes);
    for (int d = 0; d < 3; ++d) {
      const auto& x = nodes[d];
      const auto expected = [&](double v) -> std::int64_t {
        if (!(v >= x.front())) return -1;
        return std::int64_t(std::upper_bound(x.begin(), x.end(), v) - x.begin()) - 1;
      };
      std::vector<double> probes{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                                 -std::numeric_limits<double>::infinity(), x.front() - 1, x.back() + 1};
      for (const double node : x)
        probes.insert(probes.end(), {node, std::nextafter(node, -1e300), std::nextafter(node, 1e300)});
      for (int i = 0; i < 2000; ++i) probes.push_back(x.front() + (x.back() - x.front()) * (1.2 * u(rng) - 0.1));
      for (const double v : probes) ASSERT_EQ(grid.axis_index(d, v), expected(v)) << "trial " << trial << " x " << v;
    }
  }
}

TEST(RectilinearEngine, UniformNodesGiveTheCartesianFields) {
  const Particles p = random_spheres(1, 300, 0.8, 7.2, 0.3, 0.7);
  Engine cart(grid(1.0, 8, 8, 8));
  Engine rect(RectilinearGridSpec{{uniform_nodes(0, 1, 8), uniform_nodes(0, 1, 8), uniform_nodes(0, 1, 8)}});
  ASSERT_EQ(rect.cell_count(), 512);
  EXPECT_TRUE(rect.is_polymesh());
  std::vector<double> vc(512), vr(512);
  cart.cell_volumes(vc);
  rect.cell_volumes(vr);
  EXPECT_LT(l1(vc, vr), 1e-12);
  for (const char* opts : {"method=direct", "method=pmm particle_grid=100", "method=pmm", "method=exact"}) {
    const auto a = run(cart, p, opts);
    const auto b = run(rect, p, opts);
    EXPECT_LT(l1(a, b), 1e-9 * p.volume()) << opts;
    EXPECT_NEAR(total(b), p.volume(), 1e-12 * p.volume()) << opts;
  }
}

TEST(RectilinearEngine, GradedExactEqualsFineCartesianExactSummedPerCell) {
  // Graded nodes on a 0.25 lattice: each graded cell is a block of fine Cartesian cells.
  const std::vector<double> x = {0, 0.5, 1.25, 2.5, 4.0, 4.75, 6.0};
  const std::vector<double> y = {0, 1.0, 1.5, 1.75, 3.0, 6.0};
  const std::vector<double> z = {0, 2.0, 2.25, 3.5, 6.0};
  Engine rect(RectilinearGridSpec{{x, y, z}});
  Engine fine(grid(0.25, 24, 24, 24));
  const Particles p = random_spheres(2, 150, 0.6, 5.4, 0.2, 0.6);
  const auto coarse = run(rect, p, "method=exact outside=error");
  const auto fine_field = run(fine, p, "method=exact outside=error");
  std::vector<double> summed(coarse.size(), 0.0);
  auto axis_cell = [](const std::vector<double>& nodes, double u) {
    std::size_t i = 0;
    while (i + 2 < nodes.size() && u >= nodes[i + 1]) ++i;
    return static_cast<std::int64_t>(i);
  };
  const std::int64_t nx = x.size() - 1, ny = y.size() - 1;
  for (std::int64_t c = 0; c < fine.cell_count(); ++c) {
    const double u = 0.25 * (c % 24 + 0.5), v = 0.25 * ((c / 24) % 24 + 0.5), w = 0.25 * (c / 576 + 0.5);
    summed[axis_cell(x, u) + nx * (axis_cell(y, v) + ny * axis_cell(z, w))] += fine_field[c];
  }
  EXPECT_LT(l1(coarse, summed), 1e-12 * p.volume());
  // pmm and direct conserve the volume and pmm is far closer to exact than direct.
  const auto pmm = run(rect, p, "method=pmm particle_grid=2000 outside=error");
  const auto direct = run(rect, p, "method=direct outside=error");
  EXPECT_NEAR(total(pmm), p.volume(), 1e-12 * p.volume());
  EXPECT_NEAR(total(direct), p.volume(), 1e-12 * p.volume());
  EXPECT_LT(l1(pmm, coarse), 0.2 * l1(direct, coarse));
}

TEST(RectilinearEngine, PeriodicAxesWrapLikeTheCartesianGrid) {
  Particles p;  // spheres across every side and corner
  p.add(0.1, 3.0, 3.0, 0.6);
  p.add(5.9, 0.2, 3.0, 0.5);
  p.add(0.2, 5.8, 0.3, 0.7);
  p.add(7.5, 3.0, -0.4, 0.4);  // centre beyond the box: wrapped in
  Engine cart(grid(1.0, 6, 6, 6));
  Engine rect(RectilinearGridSpec{{uniform_nodes(0, 1, 6), uniform_nodes(0, 1, 6), uniform_nodes(0, 1, 6)}});
  for (const char* opts : {"method=direct", "method=pmm particle_grid=500", "method=exact"}) {
    const std::string o = std::string(opts) + " periodic=xyz outside=error";
    const auto a = run(cart, p, o);
    const auto b = run(rect, p, o);
    EXPECT_NEAR(total(b), p.volume(), 1e-12 * p.volume()) << opts;
    EXPECT_LT(l1(a, b), 1e-9 * p.volume()) << opts;
  }
  // One periodic axis: what leaves through another side is outside the mesh.
  rect.configure("method=exact periodic=x outside=drop");
  std::vector<double> out(rect.cell_count());
  rect.compute(p.view(), out);
  EXPECT_GT(rect.last_report().dropped_volume, 0.0);
  EXPECT_NEAR(total(out) + rect.last_report().dropped_volume, p.volume(), 1e-12 * p.volume());
}

TEST(RectilinearEngine, BadNodesAndUnsupportedMethodsGiveClearErrors) {
  try {
    Engine e(RectilinearGridSpec{{std::vector<double>{0, 1, 1}, {0, 1}, {0, 1}}});
    FAIL();
  } catch (const Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(err.what()).find("strictly increasing"), std::string::npos) << err.what();
  }
  Engine e(RectilinearGridSpec{{uniform_nodes(0, 1, 2), uniform_nodes(0, 1, 2), uniform_nodes(0, 1, 2)}});
  Particles p;
  p.add(1, 1, 1, 0.3);
  // Every method runs on a rectilinear grid and conserves volume.
  std::vector<double> out(e.cell_count());
  for (const std::string_view m : vfe::method_names()) {
    e.configure("method=" + std::string(m));
    e.compute(p.view(), out);
    EXPECT_NEAR(std::accumulate(out.begin(), out.end(), 0.0), 4.0 / 3.0 * std::numbers::pi * 0.027, 1e-12) << m;
  }
}

TEST(PolyMeshPeriodic, CyclicPatchesAndPeriodicOptionGiveClearErrors) {
  namespace fs = std::filesystem;
  const fs::path src = fs::path(VFE_SOURCE_DIR) / "data/openfoam/box_uniform_10x10x30/constant/polyMesh";
  const fs::path dir = fs::temp_directory_path() / ("vfe_cyclic_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const auto& f : fs::directory_iterator(src)) fs::copy_file(f.path(), dir / f.path().filename());
  {
    Engine plain(PolyMeshSpec{dir.string()});  // the copy is a valid mesh
    try {
      plain.configure("periodic=z");
      FAIL();
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
      EXPECT_NE(std::string(err.what()).find("cyclic"), std::string::npos) << err.what();
    }
  }
  std::stringstream text;
  text << std::ifstream(dir / "boundary").rdbuf();
  std::string b = text.str();
  const auto at = b.find("type            patch;");
  ASSERT_NE(at, std::string::npos);
  b.replace(at, 22, "type cyclic; neighbourPatch outlet;");
  std::ofstream(dir / "boundary") << b;
  try {
    Engine cyclic(PolyMeshSpec{dir.string()});
    FAIL();
  } catch (const Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
    EXPECT_NE(std::string(err.what()).find("'inlet' is of type cyclic"), std::string::npos) << err.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vfe::test

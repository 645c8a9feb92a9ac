// Non-spherical particles through the engine: conservation, rotation invariance,
// convergence of an ellipsoid's cell fractions, mesh files and bad specs.
#include <vfe/engine.hpp>
#include <vfe/measures.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

namespace {

vfe::CartesianGridSpec grid(double h, std::int64_t n) {
  vfe::CartesianGridSpec g;
  g.spacing = {h, h, h};
  g.cells = {n, n, n};
  return g;
}

struct Scene {
  std::vector<double> centres, scales, quats;
  std::vector<std::int32_t> ids;
  vfe::ParticleView view() const {
    vfe::ParticleView v;
    v.n = static_cast<std::int64_t>(ids.size());
    v.centres = centres.data();
    v.radii = scales.data();
    v.orientations = quats.empty() ? nullptr : quats.data();
    v.shape_ids = ids.data();
    return v;
  }
};

double sum(const std::vector<double>& f) {
  double s = 0;
  for (double x : f) s += x;
  return s;
}

std::filesystem::path temp_file(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("vfe_shape_" + name);
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

const char* kCubeObj =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n"
    "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";

}  // namespace

// shape_reach bounds how far a shape reaches from its origin in any rotation: the sphere's
// radius, else the farthest corner of the bounding box (analytic here).
TEST(EngineShapes, ShapeReachIsTheFarthestBoundingBoxCorner) {
  vfe::Engine e(grid(1.0, 4));
  EXPECT_EQ(e.shape_reach(e.add_shape("sphere")), 1.0);
  EXPECT_NEAR(e.shape_reach(e.add_shape("ellipsoid 4 0.7 0.6")), std::sqrt(16 + 0.49 + 0.36), 1e-12);
  // Spheres at (0,0,0) r 0.4 and (0.4,0,0) r 0.3: x in [-0.4, 0.7], y and z in [-0.4, 0.4].
  EXPECT_NEAR(e.shape_reach(e.add_shape("clump 0 0 0 0.4; 0.4 0 0 0.3")), std::sqrt(0.49 + 0.16 + 0.16), 1e-12);
  EXPECT_NEAR(e.shape_reach(e.add_shape("mesh " + temp_file("cube_reach.obj", kCubeObj).string())), std::sqrt(3.0),
              1e-12);
  EXPECT_THROW(e.shape_reach(99), vfe::Error);
}

TEST(EngineShapes, EveryShapeConservesVolumeWithPmmAndDirect) {
  vfe::Engine e(grid(1.0, 4));
  const std::int32_t sphere = e.add_shape("sphere");
  const std::int32_t ell = e.add_shape("ellipsoid 1 0.5 0.3");
  const std::int32_t sq = e.add_shape("superquadric 0.6 0.5 0.4 0.5 0.8");
  const std::int32_t clump = e.add_shape("clump 0 0 0 0.4; 0.4 0 0 0.3");
  const std::int32_t cube = e.add_shape("mesh " + temp_file("cube.obj", kCubeObj).string());
  EXPECT_NEAR(e.shape_volume(ell), 4.0 / 3.0 * std::numbers::pi * 0.15, 1e-14);
  EXPECT_NEAR(e.shape_volume(cube), 1.0, 1e-15);
  Scene s;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(1.2, 2.8), sc(0.6, 1.0);
  double expected = 0;
  for (int i = 0; i < 100; ++i) {
    const std::int32_t id = std::int32_t(i % 5);
    s.ids.push_back(id);
    s.centres.insert(s.centres.end(), {u(rng), u(rng), u(rng)});
    s.scales.push_back(sc(rng));
    expected += e.shape_volume(id) * std::pow(s.scales.back(), 3);
  }
  (void)sphere, (void)sq, (void)clump;
  std::vector<double> out(e.cell_count());
  for (const char* m : {"method=pmm", "method=pmm particle_grid=200", "method=direct", "method=pmm"}) {
    e.configure(m);
    e.compute(s.view(), out);
    EXPECT_NEAR(sum(out), expected, 1e-12 * expected) << m;
    EXPECT_NEAR(e.last_report().particle_volume, expected, 1e-12 * expected) << m;
  }
  e.configure("method=exact");
  try {
    e.compute(s.view(), out);
    FAIL() << "exact with shapes should be unsupported";
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
    EXPECT_NE(std::string(err.what()).find("pmm"), std::string::npos) << err.what();
  }
}

TEST(EngineShapes, GivenOrientationMovesVolumeButKeepsTheTotal) {
  vfe::Engine e(grid(0.25, 8));
  const std::int32_t ell = e.add_shape("ellipsoid 0.8 0.2 0.2");
  Scene s;
  s.ids = {ell};
  s.centres = {1.0, 1.0, 1.0};
  s.scales = {1.0};
  e.configure("method=pmm particle_grid=500 orientation=given deterministic=1");
  std::vector<double> along_x(e.cell_count()), along_z(e.cell_count());
  s.quats = {1, 0, 0, 0};
  e.compute(s.view(), along_x);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()));
  s.quats = {q.w(), q.x(), q.y(), q.z()};
  e.compute(s.view(), along_z);
  EXPECT_NEAR(sum(along_x), sum(along_z), 1e-14);
  // Along x the long axis reaches cells at x in [0.25, 0.5) (centre 1.0, half-length 0.8);
  // turned onto z it does not.
  auto column_x = [&](const std::vector<double>& f, int i) { return f[i + 8 * (4 + 8 * 4)]; };
  EXPECT_GT(column_x(along_x, 1), 0.0);
  EXPECT_EQ(column_x(along_z, 1), 0.0);
}

TEST(EngineShapes, EllipsoidCellFractionsConvergeUnderRefinement) {
  vfe::Engine e(grid(0.5, 6));
  const std::int32_t ell = e.add_shape("ellipsoid 0.7 0.45 0.3");
  Scene s;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(1.0, 2.0);
  for (int i = 0; i < 40; ++i) {
    s.ids.push_back(ell);
    s.centres.insert(s.centres.end(), {u(rng), u(rng), u(rng)});
    s.scales.push_back(1.0);
  }
  std::vector<double> ref(e.cell_count()), f(e.cell_count()), vc(e.cell_count(), 0.125);
  e.configure("method=pmm particle_grid=32768 deterministic=1");
  e.compute(s.view(), ref);
  double previous = 1e300;
  for (int n : {64, 512, 4096}) {
    e.configure("method=pmm deterministic=1 particle_grid=" + std::to_string(n));
    e.compute(s.view(), f);
    const double l1 = vfe::compare_fields(f, ref, vc, e.last_report().particle_volume).l1;
    EXPECT_LT(l1, previous) << n;
    previous = l1;
  }
  EXPECT_LT(previous, 0.01);
}

TEST(EngineShapes, StlFilesAsciiAndBinaryAndBadSpecs) {
  // A tetrahedron as ASCII STL and as binary STL.
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int tris[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::string ascii = "solid tet\n";
  std::string binary(80, ' ');
  const std::uint32_t count = 4;
  binary.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& t : tris) {
    ascii += " facet normal 0 0 0\n  outer loop\n";
    const float normal[3] = {0, 0, 0};
    binary.append(reinterpret_cast<const char*>(normal), 12);
    for (int k = 0; k < 3; ++k) {
      ascii += "   vertex " + std::to_string(v[t[k]][0]) + " " + std::to_string(v[t[k]][1]) + " " +
               std::to_string(v[t[k]][2]) + "\n";
      binary.append(reinterpret_cast<const char*>(v[t[k]]), 12);
    }
    ascii += "  endloop\n endfacet\n";
    binary.append(2, '\0');
  }
  ascii += "endsolid tet\n";
  vfe::Engine e(grid(1.0, 2));
  EXPECT_NEAR(e.shape_volume(e.add_shape("mesh " + temp_file("tet.stl", ascii).string())), 1.0 / 6.0, 1e-15);
  EXPECT_NEAR(e.shape_volume(e.add_shape("mesh " + temp_file("tetb.stl", binary).string())), 1.0 / 6.0, 1e-15);

  auto expect_error = [&](const std::string& spec, vfe_status status, const std::string& words) {
    try {
      e.add_shape(spec);
      ADD_FAILURE() << "no error for " << spec;
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), status) << spec;
      EXPECT_NE(std::string(err.what()).find(words), std::string::npos) << err.what();
    }
  };
  std::string open_cube = kCubeObj;
  open_cube.resize(open_cube.rfind("f "));  // drop the last face: a hole
  expect_error("mesh " + temp_file("open.obj", open_cube).string(), VFE_ERROR_INVALID_ARGUMENT, "open");
  expect_error("mesh /no/such/file.stl", VFE_ERROR_IO, "cannot open");
  expect_error("ellipsoid 1 2", VFE_ERROR_INVALID_ARGUMENT, "needs 3 numbers");
  expect_error("ellipsoid 1 -2 3", VFE_ERROR_INVALID_ARGUMENT, "> 0");
  expect_error("cylinder 1 2", VFE_ERROR_INVALID_ARGUMENT, "unknown shape");
  expect_error("superquadric 1 1 1 5 1", VFE_ERROR_INVALID_ARGUMENT, "exponents");
  // A shape id that is not registered.
  Scene s;
  s.ids = {7};
  s.centres = {1, 1, 1};
  s.scales = {0.3};
  std::vector<double> out(e.cell_count());
  try {
    e.compute(s.view(), out);
    FAIL();
  } catch (const vfe::Error& err) {
    EXPECT_NE(std::string(err.what()).find("shape id 7"), std::string::npos) << err.what();
  }
}

// OBJ face indices were read with atoi: "4294967300" became 4, "1x" 1 and "2.9" 2. Every
// number is now parsed whole, and a folder given as a mesh file is an I/O error.
TEST(EngineShapes, ObjAndStlNumbersAreParsedStrictlyAndFoldersAreIoErrors) {
  vfe::Engine e(grid(1.0, 2));
  const auto status_of = [&](const std::string& spec, const std::string& words) {
    try {
      e.add_shape(spec);
      ADD_FAILURE() << "no error for " << spec;
      return VFE_OK;
    } catch (const vfe::Error& err) {
      EXPECT_NE(std::string(err.what()).find(words), std::string::npos) << err.what();
      return err.status();
    }
  };
  const std::string cube = kCubeObj;
  ASSERT_NE(cube.find("\nf 1 "), std::string::npos);
  for (const char* bad_index : {"4294967300", "1x", "2.9", "0", "+", "9"}) {
    std::string text = cube;
    text.replace(text.find("\nf 1 ") + 3, 1, bad_index);
    EXPECT_EQ(status_of("mesh " + temp_file("bad_index.obj", text).string(), "face reference"),
              VFE_ERROR_INVALID_ARGUMENT) << bad_index;
  }
  std::string bad_vertex = cube;
  bad_vertex.replace(bad_vertex.find("v ") + 2, 1, "0.5.5");
  EXPECT_EQ(status_of("mesh " + temp_file("bad_vertex.obj", bad_vertex).string(), "not a finite number"),
            VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(status_of("mesh " + temp_file("bad.stl", "solid s\nfacet\nouter loop\nvertex 0 0 1e999\n").string(),
                      "not a finite number"),
            VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(status_of("mesh " + temp_file("cut.stl", "solid s\nfacet\nouter loop\nvertex 0 0 1\nvertex 0 1 1\n").string(),
                      "ends inside a facet"),
            VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(status_of("ellipsoid 1 2 3x", "not a finite number"), VFE_ERROR_INVALID_ARGUMENT);
  // A folder named like a mesh file, through the C API too.
  const auto folder = std::filesystem::temp_directory_path() / "vfe_folder_as_mesh.stl";
  std::filesystem::create_directories(folder);
  EXPECT_EQ(status_of("mesh " + folder.string(), "is a folder"), VFE_ERROR_IO);
  vfe_engine* c = nullptr;
  const double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1};
  const int64_t cells[3] = {2, 2, 2};
  ASSERT_EQ(vfe_create_cartesian(origin, spacing, cells, &c), VFE_OK);
  int32_t id = -5;
  EXPECT_EQ(vfe_add_shape(c, ("mesh " + folder.string()).c_str(), &id), VFE_ERROR_IO);
  EXPECT_EQ(id, -5);
  EXPECT_NE(std::string(vfe_last_error(c)).find("is a folder"), std::string::npos);
  vfe_destroy(c);
  std::filesystem::remove(folder);
}

// Shapes whose sampling cost grew with their bounding box: they are refused when
// registered (naming the limit) or sampled within the body itself.
TEST(EngineShapes, CostlyShapesAreRefusedUpFrontAndStrayVerticesIgnored) {
  vfe::Engine e(grid(1.0, 4));
  const auto refused = [&](const std::string& spec) {
    try {
      e.add_shape(spec);
      ADD_FAILURE() << "accepted " << spec;
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_NE(std::string(err.what()).find("limit"), std::string::npos) << err.what();
    }
  };
  refused("clump 0 0 0 1; 1e9 0 0 1");
  refused("superquadric 1 1 1e-9 1 1");
  // A box 1 x 1 x 1e-9 (the cube's faces on flattened vertices).
  const std::string cube = kCubeObj;
  const std::string flat = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1e-9\nv 1 0 1e-9\nv 0 1 1e-9\nv 1 1 1e-9\n" +
                           cube.substr(cube.find("f "));
  refused("mesh " + temp_file("flat.obj", flat).string());
  // One unused vertex far away leaves the shape and its cost as they were.
  const std::string stray = std::string(kCubeObj) + "v 1e300 -1e300 1e300\n";
  const auto t0 = std::chrono::steady_clock::now();
  const auto id = e.add_shape("mesh " + temp_file("stray.obj", stray).string());
  EXPECT_NEAR(e.shape_volume(id), 1.0, 1e-12);
  Scene s;
  s.ids = {id};
  s.centres = {2, 2, 2};
  s.scales = {0.4};
  std::vector<double> out(e.cell_count());
  e.configure("method=pmm particle_grid=50");
  e.compute(s.view(), out);
  double total = 0;
  for (const double v : out) total += v;
  EXPECT_NEAR(total, 0.4 * 0.4 * 0.4, 1e-12);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
}

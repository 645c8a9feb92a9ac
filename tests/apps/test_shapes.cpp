// Shaped particles in scenes: generated ellipsoids end to end, a dump whose type (or shape)
// column picks the shapes with quaternion columns, and config errors that name the key and
// the file.
#include "config.hpp"
#include "dump_reader.hpp"
#include "run.hpp"
#include "scene_particles.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

const std::string kGenerated = R"(name: ellipsoids
shapes:
  - {name: ell, spec: "ellipsoid 1 0.6 0.4"}
particles:
  generate: {count: 12, shape: ell, scale: 0.001, box: [0.001, 0.007, 0.001, 0.007, 0.001, 0.007], seed: 3}
meshes:
  - {name: coarse, bounds: [0, 0.008, 0, 0.008, 0, 0.008], spacing: 0.002}
methods:
  - direct
  - pmm
  - {method: pmm, options: "particle_grid=27", label: pmm_27}
  - gaussian
threads: 1
repeats: 1
output: out
)";

const std::string kCube = R"(v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
)";

/// Four particles: types 1 2 1 2, radius = scale, quaternions (one not unit-length free).
std::string typed_dump(const std::string& extra_column = "", const std::string& extra_values = "") {
  std::string s =
      "ITEM: TIMESTEP\n10\nITEM: NUMBER OF ATOMS\n4\nITEM: BOX BOUNDS ff ff ff\n0 0.008\n0 0.008\n0 0.008\n"
      "ITEM: ATOMS id type x y z radius quatw quati quatj quatk" + extra_column + "\n";
  const char* lines[4] = {"1 1 0.002 0.002 0.002 0.001 1 0 0 0",
                          "2 2 0.006 0.002 0.002 0.0008 0.5 0.5 0.5 0.5",
                          "3 1 0.002 0.006 0.006 0.0009 0 0 0 1",
                          "4 2 0.006 0.006 0.006 0.0007 0.8 0.6 0 0"};
  std::istringstream extra(extra_values);
  for (const char* l : lines) {
    std::string v;
    extra >> v;
    s += std::string(l) + (extra_column.empty() ? "" : " " + v) + "\n";
  }
  return s;
}

std::string typed_config(const std::string& shape_by_type = "{1: ell, 2: cube}") {
  return "name: typed\nshapes:\n  - {name: ell, spec: \"ellipsoid 1 0.6 0.4\"}\n"
         "  - {name: cube, spec: \"mesh shapes/cube.obj\"}\n"
         "particles:\n  file: data/typed.dump\n  shape_by_type: " + shape_by_type +
         "\nmeshes:\n  - {name: grid, bounds: particles_box, spacing: 0.002}\n"
         "methods: [direct, pmm]\nthreads: 1\nrepeats: 1\noutput: out\n";
}

struct TypedScene {
  test::TempDir dir;
  fs::path config;
  explicit TypedScene(const std::string& cfg = typed_config(), const std::string& dump = typed_dump()) {
    fs::create_directories(dir / "data");
    fs::create_directories(dir / "shapes");
    test::write_text(dir / "shapes" / "cube.obj", kCube);
    test::write_text(dir / "data" / "typed.dump", dump);
    config = dir / "typed.yaml";
    test::write_text(config, cfg);
  }
};

/// The ConfigError message of parsing text (empty when it parses).
std::string config_error(const std::string& text, const fs::path& base = ".") {
  try {
    (void)parse_config(text, base, "scene.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ShapedScene, GeneratedEllipsoidsEndToEnd) {
  test::TempDir dir;
  test::write_text(dir / "ell.yaml", kGenerated);
  const SceneConfig cfg = load_config(dir / "ell.yaml");
  ASSERT_TRUE(cfg.shaped());
  EXPECT_EQ(cfg.reference.method, "pmm");  // the scenes' default reference for shapes
  EXPECT_EQ(cfg.reference.options, "particle_grid=4000");

  std::ostringstream table;
  RunOptions opt;
  opt.table = &table;
  const RunResult res = run_scene(cfg, opt);
  ASSERT_TRUE(fs::exists(res.output / "results.csv"));
  ASSERT_TRUE(fs::exists(res.output / "results.json"));
  ASSERT_EQ(res.rows.size(), 5u);  // 4 methods + the reference
  const double ell_volume = 4.0 / 3.0 * std::numbers::pi * 0.24e-9;
  int skipped = 0;
  for (const ResultRow& r : res.rows) {
    SCOPED_TRACE(r.label);
    if (r.method == "gaussian") {  // a method for spheres only
      ++skipped;
      EXPECT_TRUE(r.skipped);
      EXPECT_NE(r.note.find("spheres only"), std::string::npos) << r.note;
      continue;
    }
    EXPECT_FALSE(r.skipped);
    EXPECT_LT(r.accuracy.volume_error, 1e-9);
    EXPECT_NEAR(r.particle_volume, 12 * ell_volume, 1e-12 * 12 * ell_volume);
    EXPECT_NE(r.options.find("orientation=given"), std::string::npos) << r.options;
    if (r.is_reference) {
      EXPECT_NEAR(static_cast<double>(r.particle_grid_max), 4000.0, 40.0);  // the nearest template size
    }
  }
  EXPECT_EQ(skipped, 1);
  const std::string csv = test::read_text(res.output / "results.csv");
  EXPECT_NE(csv.find("skipped"), std::string::npos);
  EXPECT_NE(table.str().find("gaussian skipped"), std::string::npos) << table.str();
  EXPECT_NE(test::read_text(res.output / "results.json").find("\"particles_file\": \"generated\""), std::string::npos);
}

TEST(ShapedScene, GeneratorIsSeededAndOrientationsAreUnit) {
  GenerateSpec g;
  g.count = 200;
  g.shape = "ell";
  g.scale = 1;
  g.box = {0, 1, 2, 4, -1, 0};
  g.seed = 5;
  std::vector<double> c1, q1, c2, q2;
  generate_particles(g, c1, q1);
  generate_particles(g, c2, q2);
  EXPECT_EQ(c1, c2);
  EXPECT_EQ(q1, q2);
  ASSERT_EQ(c1.size(), 600u);
  ASSERT_EQ(q1.size(), 800u);
  for (std::size_t i = 0; i < 200; ++i) {
    for (int d = 0; d < 3; ++d) {
      EXPECT_GE(c1[3 * i + d], g.box[2 * d]);
      EXPECT_LE(c1[3 * i + d], g.box[2 * d + 1]);
    }
    const double* q = &q1[4 * i];
    EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-12);
  }
  g.seed = 6;
  generate_particles(g, c2, q2);
  EXPECT_NE(c1, c2);
  g.orientations = "none";
  generate_particles(g, c2, q2);
  EXPECT_TRUE(q2.empty());
}

TEST(ShapedScene, DumpTypesPickShapesWithQuaternions) {
  TypedScene scene;
  const SceneConfig cfg = load_config(scene.config);
  ASSERT_EQ(cfg.shapes.size(), 2u);
  // The mesh path is resolved against the config's folder.
  EXPECT_NE(cfg.shapes[1].spec.find((scene.dir.path() / "shapes" / "cube.obj").lexically_normal().string()),
            std::string::npos)
      << cfg.shapes[1].spec;
  const SceneParticles p = load_particles(cfg);
  ASSERT_EQ(p.n, 4);
  EXPECT_EQ(p.shape_ids, (std::vector<std::int32_t>{0, 1, 0, 1}));
  ASSERT_EQ(p.orientations.size(), 16u);
  EXPECT_DOUBLE_EQ(p.orientations[4], 0.5);
  EXPECT_DOUBLE_EQ(p.orientations[13], 0.6);
  EXPECT_DOUBLE_EQ(p.radii[1], 0.0008);
  EXPECT_EQ(p.options, "orientation=given");
  const double ell = 4.0 / 3.0 * std::numbers::pi * 0.24;
  const double expected = ell * (1e-9 + 0.729e-9) + 1.0 * (0.512e-9 + 0.343e-9);
  EXPECT_NEAR(p.total_volume(), expected, 1e-12 * expected);

  const RunResult res = run_scene(cfg, RunOptions{});
  ASSERT_EQ(res.rows.size(), 3u);  // direct, pmm, the reference pmm
  for (const ResultRow& r : res.rows) {
    SCOPED_TRACE(r.label);
    EXPECT_FALSE(r.skipped);
    EXPECT_NEAR(r.particle_volume, expected, 1e-12 * expected);
    EXPECT_LT(r.accuracy.volume_error, 1e-9);
  }
}

TEST(ShapedScene, ShapeColumnWinsOverType) {
  // shape column 2 1 2 1: the opposite of the types.
  TypedScene scene(typed_config(), typed_dump(" shape", "2 1 2 1"));
  const DumpFrame f = read_dump_frame((scene.dir / "data" / "typed.dump").string());
  EXPECT_EQ(f.shapes, (std::vector<std::int32_t>{2, 1, 2, 1}));
  const SceneParticles p = load_particles(load_config(scene.config));
  EXPECT_EQ(p.shape_ids, (std::vector<std::int32_t>{1, 0, 1, 0}));
}

TEST(ShapedSceneErrors, UnmappedTypeNamesTheTypeAndParticle) {
  TypedScene scene(typed_config("{1: ell}"));
  try {
    (void)load_particles(load_config(scene.config));
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("typed.yaml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("shape_by_type"), std::string::npos) << msg;
    EXPECT_NE(msg.find("type 2"), std::string::npos) << msg;
    EXPECT_NE(msg.find("id 2"), std::string::npos) << msg;
  }
}

TEST(ShapedSceneErrors, UnknownShapeNameAndBadSpec) {
  test::TempDir dir;
  // Unknown name in shape_by_type: the key, the name, the known shapes, the file and line.
  fs::create_directories(dir / "shapes");
  test::write_text(dir / "shapes" / "cube.obj", kCube);
  test::write_text(dir / "typed.yaml", typed_config("{1: ell, 2: cubee}"));
  std::string msg;
  try {
    (void)load_config(dir / "typed.yaml");
  } catch (const ConfigError& e) {
    msg = e.what();
  }
  EXPECT_NE(msg.find("typed.yaml:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("shape_by_type"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'cubee'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("known: ell, cube"), std::string::npos) << msg;

  // Unknown name in generate.
  std::string gen = kGenerated;
  gen.replace(gen.find("shape: ell"), 10, "shape: egg");
  msg = config_error(gen);
  EXPECT_NE(msg.find("scene.yaml:5"), std::string::npos) << msg;
  EXPECT_NE(msg.find("generate: shape"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'egg'"), std::string::npos) << msg;

  // Bad spec: the shape's name, the key and the engine's reason.
  std::string bad = kGenerated;
  bad.replace(bad.find("ellipsoid 1 0.6 0.4"), 19, "ellipsoid 1 0.6");
  msg = config_error(bad);
  EXPECT_NE(msg.find("scene.yaml:3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("shapes: 'ell': spec"), std::string::npos) << msg;
  EXPECT_NE(msg.find("needs 3 numbers"), std::string::npos) << msg;
  bad = kGenerated;
  bad.replace(bad.find("ellipsoid 1 0.6 0.4"), 19, "blob 1");
  msg = config_error(bad);
  EXPECT_NE(msg.find("unknown shape 'blob'"), std::string::npos) << msg;

  // A mesh file that is not there: named, resolved against the config's folder.
  bad = kGenerated;
  bad.replace(bad.find("ellipsoid 1 0.6 0.4"), 19, "mesh nowhere/cube.obj");
  msg = config_error(bad, dir.path());
  EXPECT_NE(msg.find((dir.path() / "nowhere" / "cube.obj").string()), std::string::npos) << msg;

  // Shapes nobody uses, a generator without a box, duplicate names.
  msg = config_error("shapes: [{name: a, spec: sphere}]\nparticles: p.dump\nmeshes: [{name: m, bounds: "
                     "particles_box, spacing: 1}]\nmethods: [pmm]\n");
  EXPECT_NE(msg.find("no particle uses them"), std::string::npos) << msg;
  std::string nobox = kGenerated;
  const auto box_at = nobox.find(", box: [");
  nobox.erase(box_at, nobox.find(']', box_at) + 1 - box_at);
  msg = config_error(nobox);
  EXPECT_NE(msg.find("no 'box' key"), std::string::npos) << msg;
  std::string twice = kGenerated;
  twice.replace(twice.find("particles:"), 0, "  - {name: ell, spec: sphere}\n");
  msg = config_error(twice);
  EXPECT_NE(msg.find("two shapes are named 'ell'"), std::string::npos) << msg;
}

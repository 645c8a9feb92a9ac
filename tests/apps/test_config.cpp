// YAML scene config: the schema, relative paths, and errors that name the key and file.
#include "config.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

const std::string kGood = R"(name: bed_mono
particles:
  file: ../data/liggghts/bed_mono_final.dump.gz
meshes:
  - name: cartesian_2mm
    type: cartesian
    origin: [0, 0, 0]
    spacing: [0.002, 0.002, 0.002]
    cells: [10, 10, 30]
  - name: cartesian_1mm
    type: cartesian
    bounds: particles_box
    spacing: 0.001
methods:
  - direct
  - pmm
  - {method: pmm, options: "particle_grid=27 template=fibonacci", label: pmm_fib27}
  - {method: pmm, options: "particle_grid=8"}
reference: exact
threads: 2
repeats: 3
options: "outside=nearest"
output: ../out/bed_mono
)";

/// Message of the ConfigError that parsing text throws ("" if none).
std::string error_of(const std::string& text) {
  try {
    (void)parse_config(text, "/cfg", "scene.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto p = s.find(from);
  if (p == std::string::npos) throw std::logic_error("no '" + from + "' in the config text");
  return s.replace(p, from.size(), to);
}

}  // namespace

TEST(Config, ParsesTheSchema) {
  const SceneConfig c = parse_config(kGood, "/cfg/configs", "bed.yaml");
  EXPECT_EQ(c.name, "bed_mono");
  EXPECT_EQ(c.particles_file, fs::path("/cfg/data/liggghts/bed_mono_final.dump.gz"));
  EXPECT_EQ(c.frame, -1);
  ASSERT_EQ(c.meshes.size(), 2u);
  EXPECT_EQ(c.meshes[0].name, "cartesian_2mm");
  ASSERT_TRUE(c.meshes[0].origin && c.meshes[0].spacing && c.meshes[0].cells);
  EXPECT_EQ((*c.meshes[0].cells)[2], 30);
  EXPECT_EQ((*c.meshes[0].spacing)[1], 0.002);
  EXPECT_EQ(c.meshes[0].line, 5);
  EXPECT_TRUE(c.meshes[1].bounds_particles_box);
  ASSERT_TRUE(c.meshes[1].spacing);
  EXPECT_EQ((*c.meshes[1].spacing)[2], 0.001);  // a single number for all directions
  ASSERT_EQ(c.methods.size(), 4u);
  EXPECT_EQ(c.methods[0].method, "direct");
  EXPECT_EQ(c.methods[0].label, "direct");
  EXPECT_EQ(c.methods[1].options, "");
  EXPECT_EQ(c.methods[2].method, "pmm");
  EXPECT_EQ(c.methods[2].options, "particle_grid=27 template=fibonacci");
  EXPECT_EQ(c.methods[2].label, "pmm_fib27");
  EXPECT_EQ(c.methods[3].label, "pmm_particle_grid-8");  // a label made from the options
  EXPECT_EQ(c.reference.method, "exact");
  EXPECT_EQ(c.reference.label, "exact");
  EXPECT_EQ(c.threads, 2);
  EXPECT_EQ(c.repeats, 3);
  EXPECT_EQ(c.options, "outside=nearest");
  EXPECT_EQ(c.output, fs::path("/cfg/out/bed_mono"));
  EXPECT_FALSE(c.vtk);
}

// `vfe run --methods` and `vfe study --families`: the labelled methods, in the config's
// order, the reference kept; an unknown label is named with the config's labels.
TEST(Config, KeepMethodsSelectsByLabel) {
  SceneConfig c = parse_config(kGood, "/cfg/configs", "bed.yaml");
  keep_methods(c, {});
  EXPECT_EQ(c.methods.size(), 4u);
  keep_methods(c, {"pmm_fib27", "direct"});
  ASSERT_EQ(c.methods.size(), 2u);
  EXPECT_EQ(c.methods[0].label, "direct");
  EXPECT_EQ(c.methods[1].label, "pmm_fib27");
  EXPECT_EQ(c.reference.method, "exact");
  try {
    keep_methods(c, {"exact"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'exact'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("direct, pmm_fib27"), std::string::npos) << msg;
  }
}

TEST(Config, DefaultsAndShortForms) {
  const SceneConfig c = parse_config(
      "particles: p.dump\nmeshes: [{origin: 0, spacing: 1, cells: 4}]\nmethods: [direct]\n", "/a", "/a/s.yaml");
  EXPECT_EQ(c.name, "s");
  EXPECT_EQ(c.particles_file, fs::path("/a/p.dump"));
  EXPECT_EQ(c.meshes[0].name, "mesh1");
  EXPECT_EQ((*c.meshes[0].cells)[1], 4);
  EXPECT_EQ(c.reference.method, "exact");
  EXPECT_EQ(c.threads, 0);
  EXPECT_EQ(c.repeats, 5);
  EXPECT_EQ(c.output, fs::path("/a/out/s"));
}

TEST(Config, ReferenceByLabelAndFrame) {
  std::string text = replaced(kGood, "reference: exact", "reference: pmm_fib27");
  text = replaced(text, "  file: ../data", "  frame: first\n  file: ../data");
  const SceneConfig c = parse_config(text, "/cfg", "bed.yaml");
  EXPECT_EQ(c.reference.label, "pmm_fib27");
  EXPECT_EQ(c.reference.options, "particle_grid=27 template=fibonacci");
  EXPECT_EQ(c.frame, 0);
}

TEST(Config, LoadsFileRelativeToItsFolder) {
  test::TempDir dir;
  fs::create_directories(dir / "configs");
  test::write_text(dir / "configs" / "scene.yaml", kGood);
  const SceneConfig c = load_config(dir / "configs" / "scene.yaml");
  EXPECT_EQ(c.particles_file, (dir.path() / "data/liggghts/bed_mono_final.dump.gz").lexically_normal());
  EXPECT_EQ(c.output, (dir.path() / "out/bed_mono").lexically_normal());
}

TEST(ConfigErrors, UnknownKeyIsNamedWithFileAndLine) {
  std::string msg = error_of(replaced(kGood, "threads: 2", "thread: 2"));
  EXPECT_NE(msg.find("scene.yaml:20:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown key 'thread'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("threads"), std::string::npos) << msg;  // lists the allowed keys

  msg = error_of(replaced(kGood, "    spacing: 0.001", "    spacing: 0.001\n    celss: 4"));
  EXPECT_NE(msg.find("unknown key 'celss'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mesh 'cartesian_1mm'"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "label: pmm_fib27", "lable: pmm_fib27"));
  EXPECT_NE(msg.find("unknown key 'lable'"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "  file: ../data", "  fiel: ../data"));
  EXPECT_NE(msg.find("unknown key 'fiel'"), std::string::npos) << msg;
}

TEST(ConfigErrors, MissingMesh) {
  std::string text = kGood.substr(0, kGood.find("meshes:")) + kGood.substr(kGood.find("methods:"));
  std::string msg = error_of(text);
  EXPECT_NE(msg.find("scene.yaml"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no mesh"), std::string::npos) << msg;

  msg = error_of(replaced(text, "methods:", "meshes: []\nmethods:"));
  EXPECT_NE(msg.find("no mesh"), std::string::npos) << msg;
}

TEST(ConfigErrors, BadMeshGeometry) {
  EXPECT_NE(error_of(replaced(kGood, "cells: [10, 10, 30]", "cells: [10, 10]")).find("3 integers"), std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "cells: [10, 10, 30]", "cells: [10, 0, 30]")).find("cells must be >= 1"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "spacing: [0.002, 0.002, 0.002]", "spacing: [0.002, abc, 0.002]"))
                .find("must be a number, got 'abc'"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "    cells: [10, 10, 30]\n", "")).find("needs both 'spacing' and 'cells'"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "type: cartesian", "type: tetgen")).find("unknown mesh type 'tetgen'"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "type: cartesian", "type: polymesh")).find("unknown key 'origin'"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "bounds: particles_box", "bounds: everything")).find("particles_box"),
            std::string::npos);
}

TEST(ConfigErrors, BadMethodEntry) {
  std::string msg = error_of(replaced(kGood, "  - direct\n", "  - [direct]\n"));
  EXPECT_NE(msg.find("method entry 1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("scene.yaml:15:"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "{method: pmm, options: \"particle_grid=8\"}", "{options: \"particle_grid=8\"}"));
  EXPECT_NE(msg.find("method entry 4 has no 'method' key"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "options: \"particle_grid=8\"", "options: \"particle_grid 8\""));
  EXPECT_NE(msg.find("not of the form key=value"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "  - direct\n", "  - pmm\n"));
  EXPECT_NE(msg.find("two methods have the label 'pmm'"), std::string::npos) << msg;

  msg = error_of(replaced(kGood, "  - direct\n", "  - direct method\n"));
  EXPECT_NE(msg.find("is not a method name"), std::string::npos) << msg;

  const std::string no_methods =
      kGood.substr(0, kGood.find("methods:")) + "methods: []\n" + kGood.substr(kGood.find("reference:"));
  msg = error_of(no_methods);
  EXPECT_NE(msg.find("no method"), std::string::npos) << msg;
}

TEST(ConfigErrors, BadValuesAndYaml) {
  EXPECT_NE(error_of(replaced(kGood, "repeats: 3", "repeats: 0")).find("repeats must be >= 1"), std::string::npos);
  EXPECT_NE(error_of(replaced(kGood, "threads: 2", "threads: many")).find("threads must be an integer"),
            std::string::npos);
  const std::string msg = error_of(replaced(kGood, "  - pmm\n", "  - pmm\n   - : [\n"));
  EXPECT_NE(msg.find("scene.yaml:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not valid YAML"), std::string::npos) << msg;
  EXPECT_NE(error_of("").find("empty"), std::string::npos);
  EXPECT_NE(error_of("- a\n- b\n").find("must be a map"), std::string::npos);

  try {
    (void)load_config("/nonexistent_folder_of_vfe/none.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no such config file"), std::string::npos) << e.what();
  }
}

TEST(Config, ResolvesGrids) {
  const SceneConfig c = parse_config(kGood, "/cfg", "bed.yaml");
  const std::array<double, 6> box{0, 0.02, 0, 0.02, 0, 0.06};
  auto g = resolve_grid(c.meshes[0], &box, "bed.yaml");
  EXPECT_EQ(g.cells, (std::array<std::int64_t, 3>{10, 10, 30}));
  std::string note;
  g = resolve_grid(c.meshes[1], &box, "bed.yaml", &note);
  EXPECT_EQ(g.cells, (std::array<std::int64_t, 3>{20, 20, 60}));
  EXPECT_NEAR(g.spacing[2], 0.001, 1e-15);
  EXPECT_TRUE(note.empty()) << note;

  MeshSpec m = c.meshes[1];
  m.spacing = std::array<double, 3>{0.003, 0.003, 0.003};
  g = resolve_grid(m, &box, "bed.yaml", &note);
  EXPECT_EQ(g.cells, (std::array<std::int64_t, 3>{7, 7, 20}));
  EXPECT_EQ(g.spacing[0], 0.003);
  EXPECT_FALSE(note.empty());
  EXPECT_THROW(resolve_grid(c.meshes[1], nullptr, "bed.yaml"), ConfigError);
}

TEST(Config, MergesOptions) {
  EXPECT_EQ(merge_options({"method=pmm particle_grid=auto threads=0", "threads=2", "particle_grid=27 outside=drop"}),
            "method=pmm particle_grid=27 threads=2 outside=drop");
  EXPECT_EQ(merge_options({"", "  "}), "");
  EXPECT_THROW(merge_options({"novalue"}), ConfigError);
}

TEST(Config, RectilinearMeshesFromNodeListsAndGradedAxes) {
  const std::string rect = R"(  - name: graded
    type: rectilinear
    x: [0, 0.001, 0.003, 0.02]
    y: {lo: 0, hi: 0.02, cells: 4}
    z: {lo: 0, hi: 0.06, cells: 5, grading: 4}
)";
  const SceneConfig c = parse_config(replaced(kGood, "methods:\n", rect + "methods:\n"), "/cfg", "bed.yaml");
  ASSERT_EQ(c.meshes.size(), 3u);
  const MeshSpec& m = c.meshes[2];
  EXPECT_EQ(m.type, "rectilinear");
  EXPECT_EQ(m.nodes[0], (std::vector<double>{0, 0.001, 0.003, 0.02}));
  ASSERT_EQ(m.nodes[1].size(), 5u);
  EXPECT_NEAR(m.nodes[1][2], 0.01, 1e-15);
  ASSERT_EQ(m.nodes[2].size(), 6u);
  EXPECT_EQ(m.nodes[2].front(), 0.0);
  EXPECT_EQ(m.nodes[2].back(), 0.06);
  const double first = m.nodes[2][1] - m.nodes[2][0], last = m.nodes[2][5] - m.nodes[2][4];
  EXPECT_NEAR(last / first, 4.0, 1e-12);  // grading = last cell / first cell, as blockMesh
  for (std::size_t i = 1; i < 5; ++i)      // a geometric progression
    EXPECT_NEAR((m.nodes[2][i + 1] - m.nodes[2][i]) / (m.nodes[2][i] - m.nodes[2][i - 1]), std::pow(4.0, 0.25), 1e-12);
  const std::string good = replaced(kGood, "methods:\n", rect + "methods:\n");
  EXPECT_NE(error_of(replaced(good, "x: [0, 0.001, 0.003, 0.02]", "x: [0, 0.003, 0.001]")).find("strictly increasing"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(good, "cells: 5, grading: 4", "cells: 5, grading: -1")).find("grading must be > 0"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(good, "    x: [0, 0.001, 0.003, 0.02]\n", "")).find("no 'x' axis"), std::string::npos);
  EXPECT_NE(error_of(replaced(good, "y: {lo: 0, hi: 0.02, cells: 4}", "y: {lo: 0, hi: 0.02}")).find("needs lo, hi and cells"),
            std::string::npos);
}

// A bounds spacing of 1e-200 once became a cell count of -2^63 (a double-to-integer
// conversion out of range); the count is checked before it is converted, and spacings
// whose cells cannot be computed in doubles are refused by the engine with a message.
TEST(ConfigErrors, SpacingsThatOverflowCellCountsOrVolumes) {
  const SceneConfig c = parse_config(kGood, "/cfg", "bed.yaml");
  const std::array<double, 6> box{0, 0.02, 0, 0.02, 0, 0.06};
  for (const double h : {1e-200, 5e-324, 1e-15, 0.0, -0.001}) {
    MeshSpec m = c.meshes[1];
    m.spacing = std::array<double, 3>{h, h, h};
    try {
      (void)resolve_grid(m, &box, "bed.yaml");
      ADD_FAILURE() << "accepted spacing " << h;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("at most 2^40 cells"), std::string::npos) << e.what();
    }
  }
  for (const double h : {1e-200, 5e-324, 1e200}) {
    vfe::CartesianGridSpec g;
    g.origin = {0, 0, 0};
    g.spacing = {h, h, h};
    g.cells = {2, 2, 2};
    try {
      vfe::Engine e(g);
      ADD_FAILURE() << "accepted spacing " << h;
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_NE(std::string(err.what()).find("cannot be computed in doubles"), std::string::npos) << err.what();
    }
  }
}

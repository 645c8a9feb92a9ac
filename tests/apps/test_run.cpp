// The run driver end to end on a tiny generated scene: a dump and a config in a temporary
// folder, every method against exact, reports written.
#include "config.hpp"
#include "dump_reader.hpp"
#include "run.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>

#include <cstdio>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

/// n spheres of radius 0.35-0.6 mm inside the box [0, 8 mm]^3 (plus one empty frame first).
std::string tiny_dump(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::ostringstream o;
  o.precision(10);
  o << "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n0\nITEM: BOX BOUNDS ff ff ff\n0 0.008\n0 0.008\n0 0.008\n"
    << "ITEM: ATOMS id type x y z radius \n";
  o << "ITEM: TIMESTEP\n1000\nITEM: NUMBER OF ATOMS\n" << n
    << "\nITEM: BOX BOUNDS ff ff ff\n0 0.008\n0 0.008\n0 0.008\nITEM: ATOMS id type x y z radius \n";
  for (int i = 0; i < n; ++i) {
    const double r = 0.00035 + 0.00025 * u(rng);
    o << i + 1 << " 1";
    for (int d = 0; d < 3; ++d) o << ' ' << r + (0.008 - 2 * r) * u(rng);
    o << ' ' << r << " \n";
  }
  return o.str();
}

const std::string kConfig = R"(name: tiny
particles:
  file: data/tiny.dump.gz
meshes:
  - name: coarse
    origin: [0, 0, 0]
    spacing: 0.002
    cells: [4, 4, 4]
  - name: fine
    bounds: particles_box
    spacing: 0.001
methods:
  - direct
  - pmm
  - {method: pmm, options: "particle_grid=27", label: pmm_27}
  - exact
reference: exact
threads: 1
repeats: 2
output: out
)";

struct Scene {
  test::TempDir dir;
  fs::path config;
  explicit Scene(const std::string& config_text = kConfig, int n = 60) {
    fs::create_directories(dir / "data");
    test::write_gzip(dir / "data" / "tiny.dump.gz", tiny_dump(n, 7));
    config = dir / "tiny.yaml";
    test::write_text(config, config_text);
  }
};

}  // namespace

TEST(RunDriver, TinySceneEndToEnd) {
  Scene scene;
  const SceneConfig cfg = load_config(scene.config);
  std::ostringstream table;
  RunOptions opt;
  opt.table = &table;
  opt.vtk = true;
  const RunResult res = run_scene(cfg, opt);

  EXPECT_EQ(res.output, (scene.dir.path() / "out").lexically_normal());
  ASSERT_EQ(res.rows.size(), 8u);  // 2 meshes x 4 methods
  const fs::path csv = res.output / "results.csv";
  ASSERT_TRUE(fs::exists(csv));
  ASSERT_TRUE(fs::exists(res.output / "results.json"));
  EXPECT_TRUE(fs::exists(res.output / "coarse.vti"));
  EXPECT_TRUE(fs::exists(res.output / "fine.vti"));
  EXPECT_NE(test::read_text(res.output / "coarse.vti").find("voidfraction_pmm_27"), std::string::npos);

  const auto rows = test::read_csv(csv);
  ASSERT_EQ(rows.size(), 8u);
  int exact_rows = 0;
  for (const auto& row : rows) {
    SCOPED_TRACE(row.at("mesh") + " / " + row.at("method"));
    EXPECT_EQ(row.at("scene"), "tiny");
    EXPECT_EQ(row.at("particles"), "60");
    EXPECT_EQ(row.at("threads"), "1");
    EXPECT_EQ(row.at("repeats"), "2");
    EXPECT_LT(std::stod(row.at("volume_error")), 1e-9);
    EXPECT_GT(std::stod(row.at("time_median_ms")), 0.0);
    const double chi = std::stod(row.at("chi"));
    EXPECT_GT(chi, 0.5);
    EXPECT_LT(chi, 3.0);
    if (row.at("method") == "exact") {
      ++exact_rows;
      EXPECT_EQ(row.at("reference"), "1");
      EXPECT_EQ(std::stod(row.at("theta")), 0.0);
      EXPECT_LT(std::stod(row.at("volume_error")), 1e-12);
    }
  }
  EXPECT_EQ(exact_rows, 2);
  EXPECT_EQ(rows[4].at("nx"), "8");  // fine: the 8 mm box in 1 mm cells
  EXPECT_EQ(rows[4].at("cells"), "512");

  // The table names every method.
  const std::string t = table.str();
  for (const char* label : {"direct", "pmm", "pmm_27", "exact", "mesh coarse", "mesh fine"})
    EXPECT_NE(t.find(label), std::string::npos) << label << "\n" << t;

  // The JSON holds the same rows.
  const std::string json = test::read_text(res.output / "results.json");
  EXPECT_NE(json.find("\"scene\": \"tiny\""), std::string::npos);
  EXPECT_NE(json.find("\"method\": \"pmm_27\""), std::string::npos);
}

TEST(RunDriver, CommandLineOverridesAndEmptyFrame) {
  Scene scene;
  std::string text = kConfig;
  text.replace(text.find("  file: data/tiny.dump.gz"), 25, "  file: data/tiny.dump.gz\n  frame: first");
  test::write_text(scene.config, text);
  RunOptions opt;
  opt.output = scene.dir / "elsewhere";
  opt.repeats = 1;
  opt.threads = 2;
  const RunResult res = run_scene(load_config(scene.config), opt);
  ASSERT_EQ(res.rows.size(), 8u);
  EXPECT_TRUE(fs::exists(scene.dir / "elsewhere" / "results.csv"));
  for (const auto& r : res.rows) {
    EXPECT_EQ(r.particles, 0);
    EXPECT_EQ(r.repeats, 1);
    EXPECT_EQ(r.threads, 2);
    EXPECT_EQ(r.accuracy.theta, 0.0);
  }
}

TEST(RunDriver, BadMethodOptionFailsBeforeAnyWork) {
  std::string text = kConfig;
  text.replace(text.find("particle_grid=27"), 16, "particle_grid=lots");
  Scene scene(text);
  try {
    (void)run_scene(load_config(scene.config), RunOptions{});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("tiny.yaml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("pmm_27"), std::string::npos) << msg;
    EXPECT_NE(msg.find("particle_grid"), std::string::npos) << msg;
  }
  EXPECT_FALSE(fs::exists(scene.dir / "out"));
}

TEST(RunDriver, MissingParticleFileIsNamed) {
  std::string text = kConfig;
  text.replace(text.find("data/tiny.dump.gz"), 17, "data/none.dump.gz");
  Scene scene(text);
  try {
    (void)run_scene(load_config(scene.config), RunOptions{});
    FAIL() << "no error";
  } catch (const DumpError& e) {
    EXPECT_NE(std::string(e.what()).find("none.dump.gz"), std::string::npos) << e.what();
  }
}

// A sphere of radius 0.7 mm (1.437 mm^3) centred in a 1 mm cell: direct puts all of it into
// the 1 mm^3 cell, overfull by 0.437 mm^3; exact gives the cell only the part inside it and
// overfills nothing. The run warns and reports both facts per row.
TEST(RunDriver, WarnsAboutOverfullCells) {
  test::TempDir dir;
  fs::create_directories(dir / "data");
  test::write_text(dir / "data" / "pair.dump",
                   "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS ff ff ff\n0 0.004\n0 0.004\n"
                   "0 0.004\nITEM: ATOMS id type x y z radius\n1 1 0.0015 0.0015 0.0015 0.0007\n");
  test::write_text(dir / "pair.yaml", R"(name: pair
particles:
  file: data/pair.dump
meshes:
  - name: grid
    origin: [0, 0, 0]
    spacing: 0.001
    cells: [4, 4, 4]
methods: [direct, exact]
reference: exact
threads: 1
repeats: 1
output: out
)");
  std::ostringstream log_text;
  RunOptions opt;
  opt.logger = std::make_shared<spdlog::logger>("test", std::make_shared<spdlog::sinks::ostream_sink_mt>(log_text));
  opt.logger->set_level(spdlog::level::warn);
  const RunResult res = run_scene(load_config(dir / "pair.yaml"), opt);

  const double vp = 4.0 / 3.0 * 3.14159265358979 * 0.0007 * 0.0007 * 0.0007;
  const double excess = vp - 1e-9;
  std::map<std::string, std::map<std::string, std::string>> by_method;
  for (const auto& row : test::read_csv(res.output / "results.csv")) by_method[row.at("method")] = row;
  ASSERT_EQ(by_method.size(), 2u);
  EXPECT_EQ(by_method["direct"].at("overfull_cells"), "1");
  EXPECT_NEAR(std::stod(by_method["direct"].at("overfull_volume")), excess, 1e-12 * excess);
  EXPECT_EQ(by_method["exact"].at("overfull_cells"), "0");
  EXPECT_EQ(std::stod(by_method["exact"].at("overfull_volume")), 0.0);
  const std::string json = test::read_text(res.output / "results.json");
  EXPECT_NE(json.find("\"overfull_cells\": 1"), std::string::npos);

  const std::string warned = log_text.str();
  char fraction[32];
  std::snprintf(fraction, sizeof fraction, "%.3e", excess / vp);
  EXPECT_NE(warned.find("mesh 'grid', method 'direct': 1 cell(s) hold more solid than their volume"),
            std::string::npos)
      << warned;
  EXPECT_NE(warned.find(std::string("excess ") + fraction), std::string::npos) << warned;
  EXPECT_NE(warned.find("outside=drop"), std::string::npos);
  EXPECT_EQ(warned.find("method 'exact'"), std::string::npos) << warned;
}

// `vfe study`: the config's chi grids and settings, the Pareto front, the interpolation
// along a family's front, and the study end to end on a tiny generated scene.
#include "config.hpp"
#include "run.hpp"
#include "study_cmd.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <string>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

/// n spheres of radius 0.35-0.6 mm inside the box [0, 8 mm]^3.
std::string tiny_dump(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::ostringstream o;
  o.precision(10);
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

const std::string kStudy = R"(name: tiny_study
particles:
  file: data/tiny.dump.gz
chi: [1, 2]
methods:
  - direct
  - {method: pmm, settings: ["particle_grid=5", "particle_grid=40"]}
  - divided
  - {method: gaussian, settings: ["sigma=0.25"]}
  - exact
reference: exact
threads: 1
repeats: 1
output: out
)";

std::string error_of(const std::string& text) {
  try {
    (void)parse_config(text, "/cfg", "study.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto p = s.find(from);
  if (p == std::string::npos) throw std::logic_error("no '" + from + "' in the text");
  return s.replace(p, from.size(), to);
}

}  // namespace

TEST(StudyConfig, ChiGridsAndSettings) {
  const SceneConfig c = parse_config(kStudy, "/cfg", "study.yaml");
  EXPECT_TRUE(c.meshes.empty());  // chi alone is enough
  ASSERT_EQ(c.chi.size(), 2u);
  EXPECT_EQ(c.chi[1], 2.0);
  ASSERT_EQ(c.methods.size(), 5u);
  EXPECT_EQ(c.methods[1].settings, (std::vector<std::string>{"particle_grid=5", "particle_grid=40"}));
  const MeshSpec m = chi_mesh(0.75, 0.002);
  EXPECT_EQ(m.name, "chi_0.75");
  EXPECT_TRUE(m.bounds_particles_box);
  EXPECT_DOUBLE_EQ((*m.spacing)[2], 0.0015);
  // vfe run: one method per setting.
  const auto run = expand_settings(c.methods);
  ASSERT_EQ(run.size(), 6u);
  EXPECT_EQ(run[1].label, "pmm_particle_grid-5");
  EXPECT_EQ(run[1].options, "particle_grid=5");
  EXPECT_EQ(run[4].label, "gaussian_sigma-0.25");

  EXPECT_NE(error_of(replaced(kStudy, "chi: [1, 2]", "chi: [1, -2]")).find("chi must be > 0"), std::string::npos);
  EXPECT_NE(error_of(replaced(kStudy, "chi: [1, 2]", "chi: [1, 1]")).find("twice"), std::string::npos);
  EXPECT_NE(error_of(replaced(kStudy, "chi: [1, 2]\n", "")).find("no mesh"), std::string::npos);
  EXPECT_NE(error_of(replaced(kStudy, "\"particle_grid=5\"", "\"particle_grid\"")).find("study.yaml:7"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kStudy, "\"particle_grid=5\"", "\"method=exact\"")).find("method="),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kStudy, "settings: [\"sigma=0.25\"]", "settings: []")).find("settings"),
            std::string::npos);
}

TEST(StudyFront, ParetoAndInterpolation) {
  // (time, error): (3, 0.06) is beaten by (2, 0.05).
  const Front f = make_front({{4, 0.02}, {1, 0.1}, {3, 0.06}, {2, 0.05}});
  ASSERT_EQ(f.time, (std::vector<double>{1, 2, 4}));
  std::string note;
  EXPECT_DOUBLE_EQ(front_time_at_error(f, 0.05, &note), 2.0);
  EXPECT_EQ(note, "");
  EXPECT_NEAR(front_time_at_error(f, std::sqrt(0.1 * 0.05), &note), std::sqrt(2.0), 1e-12);  // log-log midpoint
  EXPECT_DOUBLE_EQ(front_time_at_error(f, 0.2, &note), 1.0);
  EXPECT_EQ(note, ">=");
  EXPECT_TRUE(std::isnan(front_time_at_error(f, 0.01, &note)));
  EXPECT_EQ(note, "n/a");
  EXPECT_TRUE(std::isnan(front_time_at_error(f, 0.0, &note)));  // nothing but exact reaches 0
  EXPECT_NEAR(front_error_at_time(f, std::sqrt(8.0), &note), std::sqrt(0.05 * 0.02), 1e-15);
  EXPECT_DOUBLE_EQ(front_error_at_time(f, 8, &note), 0.02);
  EXPECT_EQ(note, ">=");
  EXPECT_TRUE(std::isnan(front_error_at_time(f, 0.5, &note)));
  EXPECT_EQ(note, "n/a");

  std::vector<StudyPoint> pts(4);
  const double t[] = {1, 2, 3, 10}, e[] = {0.1, 0.05, 0.06, 0};
  for (int i = 0; i < 4; ++i) {
    pts[i].mesh = "g";
    pts[i].time_median_ms = t[i];
    pts[i].accuracy.l1 = e[i];
  }
  mark_pareto(pts);
  EXPECT_TRUE(pts[0].pareto);
  EXPECT_TRUE(pts[1].pareto);
  EXPECT_FALSE(pts[2].pareto);
  EXPECT_TRUE(pts[3].pareto);  // error 0: nobody is more accurate
}

TEST(StudyDriver, TinySceneEndToEnd) {
  test::TempDir dir;
  fs::create_directories(dir / "data");
  test::write_gzip(dir / "data" / "tiny.dump.gz", tiny_dump(80, 5));
  test::write_text(dir / "study.yaml", kStudy);
  std::ostringstream table;
  StudyOptions opt;
  opt.table = &table;
  const StudyResult res = run_study(load_config(dir / "study.yaml"), opt);
  ASSERT_EQ(res.points.size(), 12u);  // 2 grids x 6 points
  for (const auto& p : res.points) {
    SCOPED_TRACE(p.mesh + " " + p.family + " " + p.setting);
    EXPECT_TRUE(p.mesh == "chi_1" || p.mesh == "chi_2");
    EXPECT_NEAR(p.chi, p.mesh == "chi_1" ? 1.0 : 2.0, 1e-12);
    EXPECT_GT(p.time_median_ms, 0.0);
    EXPECT_LT(p.accuracy.volume_error, 1e-12);
    EXPECT_EQ(p.particles, 80);
    if (p.family == "exact") {
      EXPECT_TRUE(p.is_reference);
      EXPECT_TRUE(p.pareto);
      EXPECT_LT(p.accuracy.l1, 1e-12);
    } else {
      EXPECT_GT(p.accuracy.l1, 1e-6);
    }
    if (p.family == "pmm") {
      EXPECT_EQ(p.particle_grid_max, p.setting == "particle_grid=5" ? 5 : 40);
    }
  }
  // Every non-pmm point is compared with pmm on its grid.
  EXPECT_EQ(res.comparisons.size(), 8u);
  for (const auto& c : res.comparisons) {
    EXPECT_NE(c.family, "pmm");
    if (c.family == "exact") {
      EXPECT_EQ(c.speedup_note, "n/a");
    }
  }
  for (const char* f : {"study.csv", "comparisons.csv", "study.json"}) EXPECT_TRUE(fs::exists(res.output / f)) << f;
  const std::string csv = test::read_text(res.output / "study.csv");
  EXPECT_NE(csv.find("tiny_study,chi_2,"), std::string::npos) << csv;
  EXPECT_NE(csv.find(",pmm,pmm,particle_grid=40,"), std::string::npos);
  EXPECT_NE(table.str().find("pmm against every other point"), std::string::npos);
  // `vfe run` takes the same file: chi grids, one method per setting.
  RunOptions ropt;
  ropt.output = dir / "run";
  const RunResult run = run_scene(load_config(dir / "study.yaml"), ropt);
  EXPECT_EQ(run.rows.size(), 12u);
  EXPECT_EQ(run.rows[2].label, "pmm_particle_grid-40");
  EXPECT_EQ(run.rows[0].mesh, "chi_1");
}

TEST(StudyDriver, FamiliesSelectsMethodsAndNamesUnknownOnes) {
  test::TempDir dir;
  fs::create_directories(dir / "data");
  test::write_gzip(dir / "data" / "tiny.dump.gz", tiny_dump(30, 7));
  test::write_text(dir / "study.yaml", kStudy);
  StudyOptions opt;
  opt.chi = std::vector<double>{2};
  opt.families = {"direct", "pmm"};
  const StudyResult res = run_study(load_config(dir / "study.yaml"), opt);
  ASSERT_EQ(res.points.size(), 3u);  // direct and pmm's two settings
  for (const auto& p : res.points) EXPECT_TRUE(p.family == "direct" || p.family == "pmm") << p.family;
  opt.families = {"pmm", "gauss"};
  try {
    (void)run_study(load_config(dir / "study.yaml"), opt);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'gauss'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("direct, pmm, divided, gaussian, exact"), std::string::npos) << msg;
  }
}

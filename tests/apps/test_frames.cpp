// `vfe run` on a series of frames: the series' order and ranges, the ParaView and OpenFOAM
// output per frame, the jumps against a brute force of single-frame computes, bad inputs.
#include "config.hpp"
#include "frame_series.hpp"
#include "run.hpp"
#include "test_util.hpp"
#include "vtk_writer.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

struct DumpOptions {
  bool ids = true;
  bool velocities = true;
  bool shuffled = false;  ///< write the particles in a shuffled order
  int n = 40;
};

/// One frame of n spheres (radius 0.4-0.6 mm) in the box [0, 8 mm]^3; frame k moves every
/// sphere by a fixed pseudo-random step of up to 0.3 mm per axis per k (seeded).
std::string frame_text(std::int64_t timestep, int k, const DumpOptions& o = {}) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::string> lines;
  for (int i = 0; i < o.n; ++i) {
    const double r = 0.0004 + 0.0002 * u(rng);
    std::ostringstream line;
    line.precision(12);
    if (o.ids) line << i + 1 << ' ';
    line << 1;
    double x[3];
    for (double& xd : x) xd = r + (0.008 - 2 * r) * u(rng);
    for (double& xd : x) xd = std::clamp(xd + k * 0.0003 * (u(rng) - 0.5), r, 0.008 - r);
    for (double xd : x) line << ' ' << xd;
    line << ' ' << r;
    if (o.velocities) line << ' ' << 0.01 * (i + 1) << " 0 " << -0.02 * k;
    line << " \n";
    lines.push_back(line.str());
  }
  if (o.shuffled) std::shuffle(lines.begin(), lines.end(), std::mt19937(5));
  std::ostringstream t;
  t << "ITEM: TIMESTEP\n"
    << timestep << "\nITEM: NUMBER OF ATOMS\n"
    << o.n << "\nITEM: BOX BOUNDS ff ff ff\n0 0.008\n0 0.008\n0 0.008\nITEM: ATOMS " << (o.ids ? "id " : "")
    << "type x y z radius" << (o.velocities ? " vx vy vz" : "") << " \n";
  for (const auto& l : lines) t << l;
  return t.str();
}

/// A folder with a config; the dumps are written by each test.
struct SeriesScene {
  test::TempDir dir;
  fs::path config;
  void write_config(const std::string& particles, const std::string& methods = "[direct, pmm, gaussian, exact]",
                    const std::string& extra = "") {
    config = dir / "series.yaml";
    test::write_text(config, "name: series\nparticles:\n" + particles +
                                 "meshes:\n  - {name: grid, origin: [0, 0, 0], spacing: 0.002, cells: [4, 4, 4]}\n"
                                 "methods: " + methods + "\nreference: exact\nthreads: 1\n"
                                 "options: \"outside=nearest\"\noutput: out\n" + extra);
  }
};

/// The polyMesh of the OpenFOAM tests: 10 x 10 x 30 cells of 2 mm from the origin.
const std::string kBoxMesh = "  - {name: box, type: polymesh, path: " VFE_SOURCE_DIR "/data/openfoam/box_uniform_10x10x30}\n";

/// The message of the error run_scene throws on the scene (empty when none).
std::string run_error(const fs::path& config) {
  try {
    run_scene(load_config(config), RunOptions{});
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

/// The message of the ConfigError loading the scene with these particles gives ("" if none).
std::string config_error(SeriesScene& s, const std::string& particles) {
  s.write_config(particles);
  try {
    (void)load_config(s.config);
  } catch (const ConfigError& err) {
    return err.what();
  }
  return "";
}

std::vector<std::int64_t> timesteps(const std::vector<SceneParticles>& frames) {
  std::vector<std::int64_t> t;
  for (const auto& f : frames) t.push_back(f.timestep);
  return t;
}

/// The (time, file) pairs of a .pvd file's DataSet entries.
std::vector<std::pair<double, std::string>> pvd_entries(const fs::path& pvd) {
  const std::string text = test::read_text(pvd);
  const std::regex entry(R"re(<DataSet timestep="([^"]+)" part="0" file="([^"]+)"/>)re");
  std::vector<std::pair<double, std::string>> out;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), entry); it != std::sregex_iterator(); ++it)
    out.emplace_back(std::stod((*it)[1]), (*it)[2]);
  return out;
}

}  // namespace

TEST(FrameSeries, GlobAndListAreOrderedByTimestepNotName) {
  SeriesScene s;
  // Name order s_1000, s_50, s_900; a two-frame file after them in the list.
  test::write_text(s.dir / "s_900.dump", frame_text(900, 2));
  test::write_gzip(s.dir / "s_1000.dump.gz", frame_text(1000, 3));
  test::write_text(s.dir / "s_50.dump", frame_text(50, 1));
  test::write_text(s.dir / "m.dump", frame_text(3000, 5) + frame_text(2000, 4));
  s.write_config("  files: [\"s_*.dump*\", m.dump]\n");
  const auto frames = load_frame_series(load_config(s.config));
  EXPECT_EQ(timesteps(frames), (std::vector<std::int64_t>{50, 900, 1000, 2000, 3000}));
  EXPECT_EQ(frames[0].source_name, "s_50.dump");
  EXPECT_EQ(frames[2].source_name, "s_1000.dump.gz");
  EXPECT_EQ(frames[3].source_name, "m.dump");
  EXPECT_EQ(frames[3].velocities.size(), 3u * 40);

  s.write_config("  files: \"s_*.dump*\"\n  timesteps: [900, ~]\n");
  EXPECT_EQ(timesteps(load_frame_series(load_config(s.config))), (std::vector<std::int64_t>{900, 1000}));
  s.write_config("  files: [\"s_*\", m.dump]\n  timesteps: [~, 2000]\n  frames: [1, -2]\n");
  EXPECT_EQ(timesteps(load_frame_series(load_config(s.config))), (std::vector<std::int64_t>{900, 1000}));
  s.write_config("  file: m.dump\n  frames: all\n");
  EXPECT_EQ(timesteps(load_frame_series(load_config(s.config))), (std::vector<std::int64_t>{2000, 3000}));
}

TEST(FrameSeries, ParticlesAreOrderedById) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(10, 1, {.shuffled = true}));
  test::write_text(s.dir / "b.dump", frame_text(10, 1));
  s.write_config("  files: a.dump\n");
  const SceneParticles shuffled = load_frame_series(load_config(s.config)).front();
  s.write_config("  files: b.dump\n");
  const SceneParticles ordered = load_frame_series(load_config(s.config)).front();
  ASSERT_EQ(shuffled.ids.size(), 40u);
  for (std::size_t i = 0; i < 40; ++i) EXPECT_EQ(shuffled.ids[i], static_cast<std::int64_t>(i + 1));
  EXPECT_EQ(shuffled.centres, ordered.centres);
  EXPECT_EQ(shuffled.radii, ordered.radii);
  EXPECT_EQ(shuffled.velocities, ordered.velocities);
}

TEST(RunSeries, PvdListsEveryFrameAtItsTimeWithFilesThatExist) {
  SeriesScene s;
  const std::vector<std::int64_t> steps = {1500, 3000, 4500};
  for (std::size_t k = 0; k < steps.size(); ++k)
    test::write_gzip(s.dir / ("f_" + std::to_string(steps[k]) + ".dump.gz"), frame_text(steps[k], int(k)));
  s.write_config("  files: \"f_*.dump.gz\"\n  dem_dt: 1.0e-5\n", "[pmm, exact]", "vtk: true\n");
  const RunResult res = run_scene(load_config(s.config), RunOptions{});
  for (const std::string pvd : {"grid.pvd", "particles.pvd"}) {
    SCOPED_TRACE(pvd);
    const auto entries = pvd_entries(res.output / pvd);
    ASSERT_EQ(entries.size(), steps.size());
    for (std::size_t k = 0; k < steps.size(); ++k) {
      EXPECT_DOUBLE_EQ(entries[k].first, static_cast<double>(steps[k]) * 1e-5);
      EXPECT_NE(entries[k].second.find(std::to_string(steps[k])), std::string::npos);
      ASSERT_TRUE(fs::is_regular_file(res.output / entries[k].second)) << entries[k].second;
    }
    const std::string first = test::read_text(res.output / entries[0].second);
    if (pvd == "grid.pvd") {
      EXPECT_NE(first.find("type=\"ImageData\""), std::string::npos);
      EXPECT_NE(first.find("Name=\"voidfraction_pmm\""), std::string::npos);
      EXPECT_NE(first.find("Name=\"voidfraction_exact\""), std::string::npos);
    } else {
      EXPECT_NE(first.find("NumberOfPoints=\"40\""), std::string::npos);
      for (const char* name : {"Name=\"radius\"", "Name=\"velocity\" NumberOfComponents=\"3\"", "Name=\"id\""})
        EXPECT_NE(first.find(name), std::string::npos) << name;
    }
  }
  // Without dem_dt the time is the timestep.
  s.write_config("  files: \"f_*.dump.gz\"\n", "[pmm]", "vtk: true\n");
  const RunResult plain = run_scene(load_config(s.config), RunOptions{});
  EXPECT_DOUBLE_EQ(pvd_entries(plain.output / "grid.pvd").at(2).first, 4500.0);
  ASSERT_EQ(plain.frames.size(), 3u);
  EXPECT_DOUBLE_EQ(plain.frames[1].time, 3000.0);
}

TEST(RunSeries, VtpHoldsEveryPointWithItsRadius) {
  test::TempDir dir;
  const std::vector<double> centres = {0, 0, 0, 1, 2, 3, -1, 0.5, 4}, radii = {0.1, 0.25, 0.5};
  const std::vector<double> velocities = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::vector<std::int64_t> ids = {7, 3, 9};
  write_vtp(dir / "p.vtp", centres, radii, velocities, ids, VtkEncoding::ascii);
  const std::string text = test::read_text(dir / "p.vtp");
  EXPECT_NE(text.find("type=\"PolyData\""), std::string::npos);
  EXPECT_NE(text.find("NumberOfPoints=\"3\" NumberOfVerts=\"3\""), std::string::npos);
  const std::regex radius(R"(Name="radius" format="ascii">\s*([^<]*)</DataArray>)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, radius));
  std::istringstream values(m[1].str());
  std::vector<double> read;
  for (double v; values >> v;) read.push_back(v);
  EXPECT_EQ(read, radii);
  EXPECT_NE(text.find("7 3 9"), std::string::npos);
  // Without velocities or ids those arrays are left out; a wrong size is refused.
  write_vtp(dir / "q.vtp", centres, radii, {}, {}, VtkEncoding::ascii);
  const std::string bare = test::read_text(dir / "q.vtp");
  EXPECT_EQ(bare.find("Name=\"velocity\""), std::string::npos);
  EXPECT_EQ(bare.find("Name=\"id\""), std::string::npos);
  EXPECT_THROW(write_vtp(dir / "r.vtp", std::vector<double>(6), radii, {}, {}), std::runtime_error);
}

TEST(RunSeries, TwoFrameJumpEqualsBruteForceOfSingleFrameComputes) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(100, 0));
  test::write_text(s.dir / "b.dump", frame_text(200, 3));
  s.write_config("  files: [b.dump, a.dump]\n");
  const RunResult res = run_scene(load_config(s.config), RunOptions{});
  ASSERT_EQ(res.series.size(), 4u);
  ASSERT_EQ(res.frames.size(), 8u);  // 4 methods x 2 frames

  // The same two frames, each computed afresh on its own engine.
  std::vector<DumpFrame> dumps = {read_dump_frame((s.dir / "a.dump").string()),
                                  read_dump_frame((s.dir / "b.dump").string())};
  vfe::CartesianGridSpec grid;
  grid.origin = {0, 0, 0};
  grid.spacing = {0.002, 0.002, 0.002};
  grid.cells = {4, 4, 4};
  auto eps_of = [&](const std::string& method, const DumpFrame& f) {
    vfe::Engine e(grid);
    e.configure("method=" + method + " outside=nearest threads=1");
    std::vector<double> solid(64), eps(64);
    e.compute(f.view(), solid);
    e.void_fraction(eps);
    return eps;
  };
  const auto ref0 = eps_of("exact", dumps[0]), ref1 = eps_of("exact", dumps[1]);
  for (const SeriesRow& row : res.series) {
    SCOPED_TRACE(row.label);
    const auto e0 = eps_of(row.method, dumps[0]), e1 = eps_of(row.method, dumps[1]);
    double max_excess = -1e300, sum = 0, max_exact = 0;
    int changed = 0;
    for (std::size_t c = 0; c < 64; ++c) {
      const double dm = e1[c] - e0[c], de = ref1[c] - ref0[c];
      max_excess = std::max(max_excess, std::abs(dm) - std::abs(de));
      max_exact = std::max(max_exact, std::abs(de));
      if (dm != 0 || de != 0) {
        sum += std::abs(dm) - std::abs(de);
        ++changed;
      }
    }
    ASSERT_GT(changed, 10);
    EXPECT_NEAR(row.max_excess, max_excess, 1e-12);
    EXPECT_NEAR(row.mean_excess, sum / changed, 1e-12);
    EXPECT_NEAR(row.max_exact_jump, max_exact, 1e-12);
    if (row.method == "exact") {
      EXPECT_EQ(row.max_excess, 0.0);
    }
    if (row.method == "direct") {
      EXPECT_GT(row.max_excess, 0.05);  // a whole sphere changes cells
    }
    const auto frame = std::find_if(res.frames.begin(), res.frames.end(),
                                    [&](const FrameRow& f) { return f.label == row.label && f.frame == 1; });
    ASSERT_NE(frame, res.frames.end());
    EXPECT_EQ(frame->timestep, 200);
    EXPECT_EQ(frame->changed_cells, changed);
    EXPECT_EQ(frame->max_excess, row.max_excess);
  }
  // frames.csv: a row per method and frame, the first frame without a jump.
  const std::string csv = test::read_text(res.output / "frames.csv");
  EXPECT_EQ(csv.rfind("method,mesh,frame,timestep,time,ms,max_excess,mean_excess,max_exact_jump,changed_cells\n", 0),
            0u);
  EXPECT_NE(csv.find("\npmm,grid,0,100,100,"), std::string::npos);
  EXPECT_NE(csv.find(",nan,nan,nan,0\n"), std::string::npos);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 9);
}

TEST(RunSeries, IncrementalCarriesTheEngineAndMatchesFreshComputes) {
  SeriesScene s;
  for (int k = 0; k < 4; ++k) test::write_text(s.dir / ("f" + std::to_string(k) + ".dump"), frame_text(10 * (k + 1), k));
  s.write_config("  files: \"f*.dump\"\n", "[pmm, exact]");
  const RunResult fresh = run_scene(load_config(s.config), RunOptions{});
  s.write_config("  files: \"f*.dump\"\n", "[{method: pmm, options: \"incremental=1\"}, exact]");
  const RunResult incremental = run_scene(load_config(s.config), RunOptions{});
  ASSERT_EQ(fresh.frames.size(), incremental.frames.size());
  for (std::size_t i = 1; i < fresh.frames.size(); ++i) {
    if (fresh.frames[i].frame == 0) continue;
    EXPECT_NEAR(fresh.frames[i].max_excess, incremental.frames[i].max_excess, 1e-12);
    EXPECT_NEAR(fresh.frames[i].mean_excess, incremental.frames[i].mean_excess, 1e-12);
  }
}

TEST(RunSeries, OpenFoamTimeFolderPerFrame) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(1000, 0));
  test::write_text(s.dir / "b.dump", frame_text(18000, 2));
  test::write_text(s.dir / "series.yaml",
                   "name: series\nparticles:\n  files: [a.dump, b.dump]\n  dem_dt: 1.0e-5\nmeshes:\n" + kBoxMesh +
                   "methods: [pmm]\nreference: exact\nthreads: 1\noutput: out\nfoam: true\n");
  const RunResult res = run_scene(load_config(s.dir / "series.yaml"), RunOptions{});
  for (const char* time : {"0.01", "0.18"}) {  // 18000 * 1e-5 is 0.18000000000000002 in doubles
    SCOPED_TRACE(time);
    const fs::path field = res.output / "box" / time / "voidfraction_pmm";
    ASSERT_TRUE(fs::is_regular_file(field));
    EXPECT_TRUE(fs::is_regular_file(res.output / "box" / time / "voidfraction"));
    EXPECT_NE(test::read_text(field).find(std::string("location    \"") + time + "\""), std::string::npos);
  }
  ASSERT_EQ(res.series.size(), 1u);
  EXPECT_GT(res.series[0].max_exact_jump, 0.0);
}

TEST(RunSeries, TimestepsFromTheCommandLine) {
  SeriesScene s;
  test::write_text(s.dir / "m.dump", frame_text(10, 0) + frame_text(20, 1) + frame_text(30, 2));
  s.write_config("  file: m.dump\n  frames: all\n");
  SceneConfig cfg = load_config(s.config);
  set_timesteps(cfg, "20:");
  EXPECT_EQ(timesteps(load_frame_series(cfg)), (std::vector<std::int64_t>{20, 30}));
  set_timesteps(cfg, ":20");
  EXPECT_EQ(timesteps(load_frame_series(cfg)), (std::vector<std::int64_t>{10, 20}));
  set_timesteps(cfg, "15:25");
  EXPECT_EQ(timesteps(load_frame_series(cfg)), (std::vector<std::int64_t>{20}));
  for (const char* bad : {"20", "a:30", "20:1x", "30:20"}) EXPECT_THROW(set_timesteps(cfg, bad), ConfigError) << bad;
  s.write_config("  file: m.dump\n");
  SceneConfig one = load_config(s.config);
  EXPECT_THROW(set_timesteps(one, "10:20"), ConfigError);
}

TEST(RunSeries, BadInputsNameTheFileAndTheFix) {
  SeriesScene s;
  s.write_config("  files: \"nothing_*.dump\"\n");
  EXPECT_NE(run_error(s.config).find("no file matches '" + (s.dir / "nothing_*.dump").string() + "'"),
            std::string::npos);
  s.write_config("  files: [missing.dump]\n");
  EXPECT_NE(run_error(s.config).find("missing.dump: no such file"), std::string::npos);

  // A frame cut short (2 of its 40 atom lines).
  test::write_text(s.dir / "a.dump", frame_text(100, 0));
  std::string cut = frame_text(200, 1);
  std::size_t at = cut.find("type x y z radius vx vy vz \n") + 27;
  for (int i = 0; i < 2; ++i) at = cut.find('\n', at + 1);
  test::write_text(s.dir / "b.dump", cut.substr(0, at + 1));
  s.write_config("  files: [a.dump, b.dump]\n");
  EXPECT_NE(run_error(s.config).find("b.dump"), std::string::npos);

  // Without ids the count must not change.
  test::write_text(s.dir / "c.dump", frame_text(100, 0, {.ids = false}));
  test::write_text(s.dir / "d.dump", frame_text(200, 1, {.ids = false, .n = 39}));
  s.write_config("  files: [c.dump, d.dump]\n");
  std::string e = run_error(s.config);
  EXPECT_NE(e.find("d.dump: timestep 200 has 39 particles"), std::string::npos) << e;
  EXPECT_NE(e.find("dump the ids"), std::string::npos) << e;
  // With ids it may (particles inserted during a pour).
  test::write_text(s.dir / "d.dump", frame_text(200, 1, {.n = 39}));
  s.write_config("  files: [a.dump, d.dump]\n");
  EXPECT_EQ(run_error(s.config), "");

  // Two frames with one timestep.
  test::write_text(s.dir / "e.dump", frame_text(100, 2));
  s.write_config("  files: [a.dump, e.dump]\n");
  e = run_error(s.config);
  EXPECT_NE(e.find("timestep 100 is also in"), std::string::npos) << e;
  EXPECT_NE(e.find("a.dump"), std::string::npos) << e;
  // Ranges that keep nothing.
  s.write_config("  files: [a.dump]\n  timesteps: [500, ~]\n");
  EXPECT_NE(run_error(s.config).find("no frame with timesteps in [500, -]"), std::string::npos);
  s.write_config("  files: [a.dump]\n  frames: [1, 3]\n");
  EXPECT_NE(run_error(s.config).find("frames [1, 3] is outside the 1 frame(s)"), std::string::npos);

  // Config keys that do not go together.
  EXPECT_NE(config_error(s, "  file: a.dump\n  files: [a.dump]\n").find("not both"), std::string::npos);
  EXPECT_NE(config_error(s, "  files: [a.dump]\n  frame: 0\n").find("'frame' picks one frame"), std::string::npos);
  EXPECT_NE(config_error(s, "  file: a.dump\n  dem_dt: 1.0e-5\n").find("belong to a series"), std::string::npos);
  EXPECT_NE(config_error(s, "  files: [a.dump]\n  dem_dt: 0\n").find("dem_dt must be > 0"), std::string::npos);
  EXPECT_NE(config_error(s, "  files: [a.dump]\n  frames: some\n").find("frames must be 'all'"), std::string::npos);
  EXPECT_NE(config_error(s, "  files: [a.dump]\n  timesteps: [9, 3]\n").find("is before from"), std::string::npos);
  EXPECT_NE(config_error(s, "  files: []\n").find("empty list"), std::string::npos);
  // Commands of one frame refuse a series.
  s.write_config("  files: [a.dump]\n");
  try {
    (void)load_particles(load_config(s.config));
    ADD_FAILURE() << "a series was taken as one frame";
  } catch (const ConfigError& err) {
    EXPECT_NE(std::string(err.what()).find("takes one frame"), std::string::npos) << err.what();
  }
}

namespace {

/// Rows of a weights CSV: (particle, cell) -> fraction.
std::map<std::pair<std::int64_t, std::int64_t>, double> weights_of(const fs::path& csv) {
  std::map<std::pair<std::int64_t, std::int64_t>, double> w;
  for (const auto& row : test::read_csv(csv)) w[{std::stoll(row.at("particle")), std::stoll(row.at("cell"))}] = std::stod(row.at("fraction"));
  return w;
}

void expect_same_weights(const fs::path& a, const fs::path& b, double tolerance) {
  const auto wa = weights_of(a), wb = weights_of(b);
  ASSERT_EQ(wa.size(), wb.size()) << a << " and " << b;
  ASSERT_GT(wa.size(), 0u);
  for (const auto& [key, fraction] : wa) {
    const auto it = wb.find(key);
    ASSERT_NE(it, wb.end()) << "particle " << key.first << ", cell " << key.second << " only in " << a;
    EXPECT_NEAR(fraction, it->second, tolerance) << "particle " << key.first << ", cell " << key.second;
  }
}

void expect_near_all(const std::vector<double>& a, const std::vector<double>& b, double tolerance) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], tolerance) << "value " << i;
}

}  // namespace

// coupling: true on a series: per frame and method the weights and Us equal a single-frame
// coupling run on that frame, also for pmm with incremental=1 (whose deposits carry over).
TEST(RunSeries, CouplingPerFrameEqualsSingleFrameRuns) {
  SeriesScene s;
  const std::vector<std::int64_t> steps = {1000, 18000};
  test::write_text(s.dir / "a.dump", frame_text(steps[0], 0));
  test::write_text(s.dir / "b.dump", frame_text(steps[1], 3));
  const std::string methods = "[pmm, exact, {method: pmm, options: \"incremental=1\", label: pmm_incremental}]";
  const std::string rest = "meshes:\n" + kBoxMesh + "methods: " + methods +
                           "\nreference: exact\nthreads: 1\nrepeats: 1\nfoam: true\ncoupling: true\n";
  test::write_text(s.dir / "series.yaml",
                   "name: series\nparticles:\n  files: [a.dump, b.dump]\n  dem_dt: 1.0e-5\noutput: out\n" + rest);
  RunOptions opt;
  opt.vtk = true;
  const RunResult series = run_scene(load_config(s.dir / "series.yaml"), opt);
  ASSERT_EQ(series.frames.size(), 6u);
  const std::vector<std::string> times = {"0.01", "0.18"};
  for (std::size_t k = 0; k < steps.size(); ++k) {
    SCOPED_TRACE("timestep " + std::to_string(steps[k]));
    const std::string dump = k == 0 ? "a.dump" : "b.dump";
    test::write_text(s.dir / "one.yaml", "name: one\nparticles:\n  file: " + dump + "\noutput: one_" +
                                             std::to_string(k) + "\n" + rest);
    const RunResult one = run_scene(load_config(s.dir / "one.yaml"), RunOptions{});
    const std::string vtu = test::read_text(series.output / "frames" / ("box_" + std::to_string(steps[k]) + ".vtu"));
    for (const std::string label : {"pmm", "exact", "pmm_incremental"}) {
      SCOPED_TRACE(label);
      // Incremental deposits are old ones moved: equal to round-off, not bitwise.
      const double tolerance = label == "pmm_incremental" ? 1e-12 : 0.0;
      expect_same_weights(series.output / "frames" / ("box_weights_" + label + "_" + std::to_string(steps[k]) + ".csv"),
                          one.output / ("box_weights_" + label + ".csv"), tolerance);
      const auto us = test::read_foam_vectors(series.output / "box" / times[k] / ("Us_" + label));
      expect_near_all(us, test::read_foam_vectors(one.output / "box" / "0" / ("Us_" + label)), 1e-12);
      EXPECT_GT(std::count_if(us.begin(), us.end(), [](double u) { return u != 0; }), 40);
      EXPECT_NE(vtu.find("Name=\"Us_" + label + "\" NumberOfComponents=\"3\""), std::string::npos);
    }
    // The plain Us beside voidfraction is the default method's (pmm).
    const std::string plain = test::read_text(series.output / "box" / times[k] / "Us"),
                      pmm = test::read_text(series.output / "box" / times[k] / "Us_pmm");
    EXPECT_EQ(plain.substr(plain.find("internalField")), pmm.substr(pmm.find("internalField")));
  }
}

// Two particles in known cells of the 2 mm box with known velocities: each weight is 1 in
// its own cell, and Us is the particle's velocity there, or in a shared cell the
// volume-weighted mean of the two; 0 elsewhere.
TEST(RunSeries, CouplingOfTwoParticlesInKnownCells) {
  SeriesScene s;
  struct P {
    double x[3], r, v[3];
  };
  auto dump = [](std::int64_t step, const std::vector<P>& ps) {
    std::ostringstream o;
    o.precision(17);
    o << "ITEM: TIMESTEP\n" << step << "\nITEM: NUMBER OF ATOMS\n" << ps.size()
      << "\nITEM: BOX BOUNDS ff ff ff\n0 0.02\n0 0.02\n0 0.06\nITEM: ATOMS id type x y z radius vx vy vz\n";
    for (std::size_t i = 0; i < ps.size(); ++i)
      o << i + 1 << " 1 " << ps[i].x[0] << ' ' << ps[i].x[1] << ' ' << ps[i].x[2] << ' ' << ps[i].r << ' ' << ps[i].v[0]
        << ' ' << ps[i].v[1] << ' ' << ps[i].v[2] << '\n';
    return o.str();
  };
  const P a{{0.001, 0.001, 0.001}, 0.0004, {1, 2, 3}};           // cell (0, 0, 0)
  const P b{{0.003, 0.001, 0.005}, 0.0005, {-1, 0, 0.5}};        // cell (1, 0, 2)
  const P a2{{0.0006, 0.001, 0.001}, 0.0004, {1, 2, 3}};         // both in cell (0, 0, 0)
  const P b2{{0.0015, 0.001, 0.001}, 0.00045, {-1, 0, 0.5}};
  test::write_text(s.dir / "f.dump", dump(10, {a, b}) + dump(20, {a2, b2}));
  test::write_text(s.dir / "series.yaml", "name: two\nparticles:\n  file: f.dump\n  frames: all\nmeshes:\n" + kBoxMesh +
                                              "methods: [direct, exact]\nreference: exact\nthreads: 1\noutput: out\n"
                                              "foam: true\ncoupling: true\n");
  const RunResult res = run_scene(load_config(s.dir / "series.yaml"), RunOptions{});
  auto cell = [](int i, int j, int k) { return static_cast<std::int64_t>(i + 10 * (j + 10 * k)); };  // blockMesh order
  const double va = std::pow(a.r, 3), vb = std::pow(b2.r, 3);  // volumes / (4/3 pi)
  struct Expect {
    std::int64_t step;
    std::string time;
    std::vector<std::int64_t> cells;                    // per particle
    std::map<std::int64_t, std::array<double, 3>> us;  // per cell with solid
  };
  std::array<double, 3> mean{};
  for (int d = 0; d < 3; ++d) mean[d] = (va * a.v[d] + vb * b.v[d]) / (va + vb);
  const std::vector<Expect> expects = {
      {10, "10", {cell(0, 0, 0), cell(1, 0, 2)}, {{cell(0, 0, 0), {1, 2, 3}}, {cell(1, 0, 2), {-1, 0, 0.5}}}},
      {20, "20", {cell(0, 0, 0), cell(0, 0, 0)}, {{cell(0, 0, 0), mean}}}};
  for (const Expect& e : expects) {
    for (const std::string label : {"direct", "exact"}) {
      SCOPED_TRACE(label + " at timestep " + std::to_string(e.step));
      const auto rows = test::read_csv(res.output / "frames" / ("box_weights_" + label + "_" + std::to_string(e.step) + ".csv"));
      ASSERT_EQ(rows.size(), 2u);
      for (std::size_t p = 0; p < 2; ++p) {
        EXPECT_EQ(std::stoll(rows[p].at("particle")), static_cast<std::int64_t>(p));
        EXPECT_EQ(std::stoll(rows[p].at("id")), static_cast<std::int64_t>(p + 1));
        EXPECT_EQ(std::stoll(rows[p].at("cell")), e.cells[p]);
        EXPECT_DOUBLE_EQ(std::stod(rows[p].at("fraction")), 1.0);
      }
      const auto us = test::read_foam_vectors(res.output / "box" / e.time / ("Us_" + label));
      ASSERT_EQ(us.size(), 3u * 3000);
      for (std::int64_t c = 0; c < 3000; ++c) {
        const auto it = e.us.find(c);
        for (int d = 0; d < 3; ++d)
          ASSERT_NEAR(us[3 * c + d], it == e.us.end() ? 0.0 : it->second[d], 1e-14) << "cell " << c << " component " << d;
      }
    }
  }
}

// coupling: true on a series whose second frame has no velocities stops before any compute,
// naming that dump, its timestep and the fix.
TEST(RunSeries, CouplingNeedsVelocitiesInEveryFrame) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(100, 0));
  test::write_text(s.dir / "b.dump", frame_text(200, 1, {.velocities = false}));
  s.write_config("  files: [a.dump, b.dump]\n", "[pmm]", "coupling: true\n");
  const std::string e = run_error(s.config);
  EXPECT_NE(e.find("coupling: true needs the particles' velocities"), std::string::npos) << e;
  EXPECT_NE(e.find("the dump b.dump has no vx vy vz columns (timestep 200)"), std::string::npos) << e;
  EXPECT_NE(e.find("dump them"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(s.dir / "out" / "frames.csv"));
}

namespace {

/// The rows of a series run without the compute times (which differ from run to run).
std::vector<std::string> rows_without_times(const RunResult& r) {
  std::vector<std::string> out;
  char buf[512];
  for (const FrameRow& f : r.frames) {
    std::snprintf(buf, sizeof buf, "%s %s %lld %lld %.17g %.17g %.17g %.17g %lld", f.mesh.c_str(), f.label.c_str(),
                  static_cast<long long>(f.frame), static_cast<long long>(f.timestep), f.time, f.max_excess,
                  f.mean_excess, f.max_exact_jump, static_cast<long long>(f.changed_cells));
    out.push_back(buf);
  }
  return out;
}

/// Lines of the frames.csv of a run (0 when there is none).
std::int64_t csv_lines(const fs::path& file) {
  if (!fs::exists(file)) return 0;
  const std::string text = test::read_text(file);
  return std::count(text.begin(), text.end(), '\n');
}

}  // namespace

// particles: {command: ...}: the frames a command prints give the fields, weights and jumps
// of the same dumps given as files.
TEST(LiveSeries, CommandOutputEqualsTheSameDumpsAsFiles) {
  SeriesScene s;
  for (int k = 0; k < 3; ++k) test::write_text(s.dir / ("f" + std::to_string(k) + ".dump"), frame_text(100 * (k + 1), k, {.shuffled = k == 1}));
  const std::string methods = "[pmm, {method: pmm, options: \"incremental=1\", label: pmm_incremental}, exact]";
  s.write_config("  files: [f0.dump, f1.dump, f2.dump]\n  dem_dt: 1.0e-5\n", methods,
                 "vtk: true\ncoupling: true\noptions: \"outside=nearest deterministic=1\"\n");
  const RunResult files = run_scene(load_config(s.config), RunOptions{});
  s.write_config("  command: \"cat f0.dump f1.dump f2.dump\"\n  dem_dt: 1.0e-5\n", methods,
                 "vtk: true\ncoupling: true\noptions: \"outside=nearest deterministic=1\"\n");
  RunOptions live_opt;
  live_opt.output = s.dir / "live";
  const RunResult live = run_scene(load_config(s.config), live_opt);
  ASSERT_EQ(live.frames.size(), 9u);
  EXPECT_EQ(rows_without_times(live), rows_without_times(files));
  ASSERT_EQ(live.series.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(live.series[i].frames, 3);
    EXPECT_EQ(live.series[i].max_excess, files.series[i].max_excess);
    EXPECT_EQ(live.series[i].mean_excess, files.series[i].mean_excess);
  }
  for (const std::string f : {"grid_100.vti", "grid_200.vti", "grid_300.vti", "particles_200.vtp",
                              "grid_weights_pmm_300.csv", "grid_weights_pmm_incremental_200.csv",
                              "grid_weights_exact_100.csv"}) {
    SCOPED_TRACE(f);
    ASSERT_TRUE(fs::is_regular_file(live.output / "frames" / f));
    EXPECT_EQ(test::read_text(live.output / "frames" / f), test::read_text(files.output / "frames" / f));
  }
  EXPECT_EQ(test::read_text(live.output / "grid.pvd"), test::read_text(files.output / "grid.pvd"));
}

// Each frame is computed, and its reports written, as soon as it is complete: the command
// prints its second frame only once frames.csv holds the first.
TEST(LiveSeries, FramesAreComputedAsTheyCome) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(100, 0));
  test::write_text(s.dir / "b.dump", frame_text(200, 1));
  s.write_config("  command: \"cat a.dump; i=0; while [ ! -s out/frames.csv ] && [ $i -lt 400 ]; do sleep 0.05; "
                 "i=$((i+1)); done; [ -s out/frames.csv ] || exit 9; cat b.dump\"\n",
                 "[pmm, exact]");
  const std::string e = run_error(s.config);
  EXPECT_EQ(e, "");
  EXPECT_EQ(csv_lines(s.dir / "out" / "frames.csv"), 1 + 2 * 2);
}

// A command that fails, prints a frame cut short, prints nothing, cannot be found or prints
// its frames out of order stops the run naming the command and what happened; the reports
// of the frames finished before are written.
TEST(LiveSeries, FailuresNameTheCommandAndKeepFinishedFrames) {
  SeriesScene s;
  test::write_text(s.dir / "a.dump", frame_text(100, 0));
  test::write_text(s.dir / "b.dump", frame_text(200, 1));
  auto live_error = [&](const std::string& command) {
    fs::remove_all(s.dir / "out");
    s.write_config("  command: \"" + command + "\"\n", "[pmm, exact]");
    return run_error(s.config);
  };
  std::string e = live_error("cat a.dump; exit 3");
  EXPECT_NE(e.find("command 'cat a.dump; exit 3' exited with status 3 (after 1 complete frame(s)"), std::string::npos)
      << e;
  EXPECT_EQ(csv_lines(s.dir / "out" / "frames.csv"), 1 + 2);
  EXPECT_EQ(test::read_csv(s.dir / "out" / "frame_jumps.csv").at(0).at("frames"), "1");

  e = live_error("cat a.dump; head -c 900 b.dump");
  EXPECT_NE(e.find("the output of command 'cat a.dump; head -c 900 b.dump'"), std::string::npos) << e;
  EXPECT_NE(e.find("after 1 complete frame(s)"), std::string::npos) << e;
  EXPECT_EQ(csv_lines(s.dir / "out" / "frames.csv"), 1 + 2);

  e = live_error("no_such_program_of_vfe");
  EXPECT_NE(e.find("command 'no_such_program_of_vfe' exited with status 127 (the shell did not find the program) "
                   "(before any complete frame)"),
            std::string::npos)
      << e;
  EXPECT_FALSE(fs::exists(s.dir / "out" / "frames.csv"));
  e = live_error("true");
  EXPECT_NE(e.find("command 'true': ended without printing a frame"), std::string::npos) << e;
  e = live_error("cat b.dump a.dump");
  EXPECT_NE(e.find("printed timestep 100 after timestep 200"), std::string::npos) << e;
  EXPECT_EQ(csv_lines(s.dir / "out" / "frames.csv"), 1 + 2);
  // Velocities are checked as frames come.
  test::write_text(s.dir / "c.dump", frame_text(300, 2, {.velocities = false}));
  fs::remove_all(s.dir / "out");
  s.write_config("  command: \"cat a.dump c.dump\"\n", "[pmm]", "coupling: true\n");
  e = run_error(s.config);
  EXPECT_NE(e.find("the dump command 'cat a.dump c.dump' has no vx vy vz columns (timestep 300)"), std::string::npos)
      << e;
  EXPECT_EQ(csv_lines(s.dir / "out" / "frames.csv"), 1 + 1);

  // Keys that do not go with a command.
  EXPECT_NE(config_error(s, "  command: \"cat a.dump\"\n  files: [a.dump]\n").find("give no 'file'"), std::string::npos);
  EXPECT_NE(config_error(s, "  command: \"cat a.dump\"\n  frames: [-2, -1]\n").find("counted as they come"),
            std::string::npos);
  EXPECT_NE(config_error(s, "  command: \"\"\n").find("command is empty"), std::string::npos);
}

// frames: [first, last] and timesteps on a command: the frames outside are read and left
// out, and once the last frame asked for is in, the command is stopped.
TEST(LiveSeries, RangesPickFramesAndStopTheCommand) {
  SeriesScene s;
  for (int k = 0; k < 4; ++k) test::write_text(s.dir / ("f" + std::to_string(k) + ".dump"), frame_text(100 * (k + 1), k));
  s.write_config("  command: \"cat f0.dump f1.dump f2.dump f3.dump\"\n  timesteps: [200, ~]\n  frames: [1, -1]\n",
                 "[pmm]");
  RunResult r = run_scene(load_config(s.config), RunOptions{});
  EXPECT_EQ(r.frames.size(), 2u);
  EXPECT_EQ(r.frames.at(0).timestep, 300);
  const auto start = std::chrono::steady_clock::now();
  s.write_config("  command: \"cat f0.dump f1.dump; sleep 60\"\n  frames: [0, 1]\n", "[pmm]");
  r = run_scene(load_config(s.config), RunOptions{});
  EXPECT_EQ(r.frames.size(), 2u);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 20.0);
}

// `vfe bench`: the generated scenes and a tiny run through run_bench (rows, rates, volume
// conservation, reports), and errors that name the bad argument.
#include "bench_cmd.hpp"
#include "test_util.hpp"
#include "timing.hpp"

#include <vfe/engine.hpp>
#include <vfe/vfe.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

using namespace vfe::apps;

namespace {

BenchCommand tiny_command(const std::filesystem::path& output) {
  BenchCommand c;
  c.scene = "bed";
  c.dispersity = "poly";
  c.particles = {2000};
  c.chi = {1, 2};
  c.threads = {1};
  c.repeats = 1;
  c.output = output;
  return c;
}

/// The message run_bench throws for a command, or "" when it does not throw.
std::string error_of(const BenchCommand& c) {
  try {
    (void)run_bench(c);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(BenchScene, FractionsAndShuffledOrder) {
  for (const char* dispersity : {"mono", "poly"}) {
    const BenchScene bed = make_bench_scene("bed", dispersity, 5000, 7);
    EXPECT_GE(bed.solid_fraction, 0.55) << dispersity;
    EXPECT_LE(bed.solid_fraction, 0.60) << dispersity;
    const BenchScene stream = make_bench_scene("stream", dispersity, 5000, 7);
    EXPECT_NEAR(stream.solid_fraction, 0.05, 1e-12) << dispersity;
    EXPECT_NEAR(bed.mean_diameter, 1.0, 0.02) << dispersity;
    ASSERT_EQ(bed.centres.size(), 3u * 5000);
    // Shuffled: the first particles are not the bottom layer of the lattice.
    double z_first = 0;
    for (int p = 0; p < 100; ++p) z_first += bed.centres[3 * p + 2] / 100;
    EXPECT_GT(z_first, 0.25 * bed.hi[2]) << dispersity;
  }
  const BenchScene a = make_bench_scene("bed", "poly", 1000, 3), b = make_bench_scene("bed", "poly", 1000, 3);
  EXPECT_EQ(a.centres, b.centres);
  EXPECT_EQ(a.radii, b.radii);
  EXPECT_NE(a.radii, make_bench_scene("bed", "poly", 1000, 4).radii);
}

TEST(BenchScene, MortonOrderKeepsTheParticlesAndPutsNeighboursTogether) {
  const BenchScene shuffled = make_bench_scene("bed", "poly", 5000, 7);
  BenchScene sorted = shuffled;
  sort_morton(sorted);
  // The same particles (centre and radius together), in another order.
  auto as_set = [](const BenchScene& s) {
    std::vector<std::array<double, 4>> v;
    for (std::int64_t p = 0; p < s.n; ++p)
      v.push_back({s.centres[3 * p], s.centres[3 * p + 1], s.centres[3 * p + 2], s.radii[p]});
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(as_set(sorted), as_set(shuffled));
  // Consecutive particles lie close: the mean step is a few diameters, not the bed's size.
  auto mean_step = [](const BenchScene& s) {
    double sum = 0;
    for (std::int64_t p = 1; p < s.n; ++p)
      sum += std::hypot(s.centres[3 * p] - s.centres[3 * p - 3], s.centres[3 * p + 1] - s.centres[3 * p - 2],
                        s.centres[3 * p + 2] - s.centres[3 * p - 1]);
    return sum / double(s.n - 1);
  };
  EXPECT_LT(mean_step(sorted), 3.0);
  EXPECT_GT(mean_step(shuffled), 5.0);
}

TEST(Bench, TinyBedRowsRatesAndVolume) {
  test::TempDir dir;
  const BenchOutcome out = run_bench(tiny_command(dir / "bench"));
  ASSERT_EQ(out.rows.size(), 6u);  // 2 chi x 3 methods x 1 thread
  ASSERT_EQ(out.limits.size(), 2u);
  for (const BenchRow& r : out.rows) {
    SCOPED_TRACE(r.method + " chi " + std::to_string(r.chi));
    EXPECT_EQ(r.particles, 2000);
    EXPECT_EQ(r.threads, 1);
    EXPECT_GT(r.time_median_ms, 0);
    EXPECT_GT(r.cells, 0);
    EXPECT_GE(r.solid_fraction, 0.55);
    EXPECT_LE(r.solid_fraction, 0.60);
    EXPECT_GT(r.sub_elements, 0);
    EXPECT_NEAR(r.sub_elements_per_s, double(r.sub_elements) / (r.time_median_ms * 1e-3), 1e-9 * r.sub_elements_per_s);
    EXPECT_NEAR(r.particles_per_s, 2000 / (r.time_median_ms * 1e-3), 1e-9 * r.particles_per_s);
    EXPECT_LT(r.volume_error, 1e-12);
    EXPECT_GT(r.bandwidth_ms, 0);
    EXPECT_GT(r.scatter_ms, 0);
    EXPECT_GT(r.locate_ms, 0);
    EXPECT_NEAR(r.x_locate, r.time_median_ms / r.locate_ms, 1e-12 * r.x_locate);
    EXPECT_TRUE(std::isnan(r.speedup));  // no 2-thread row
    EXPECT_GT(r.peak_rss_bytes, 0);
  }
  // pmm auto resolves far more sub-elements per particle at chi = 1 than at chi = 2.
  EXPECT_EQ(out.rows[1].method, "pmm");
  EXPECT_EQ(out.rows[4].method, "pmm");
  EXPECT_GT(out.rows[1].sub_elements_per_particle, 2 * out.rows[4].sub_elements_per_particle);
  for (const BenchLimit& l : out.limits) EXPECT_GE(l.locate_sub_elements, 2000);
  const std::string csv = test::read_text(out.output / "bench.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 7);
  EXPECT_NE(test::read_text(out.output / "bench.json").find("\"x_locate\""), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(out.output / "limits.csv"));
}

TEST(Bench, BadArgumentsAreNamed) {
  test::TempDir dir;
  BenchCommand c = tiny_command(dir / "bench");
  c.chi = {1, 0};
  EXPECT_NE(error_of(c).find("--chi"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.scene = "heap";
  const std::string scene_error = error_of(c);
  EXPECT_NE(scene_error.find("--scene"), std::string::npos);
  EXPECT_NE(scene_error.find("heap"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.particles = {0};
  EXPECT_NE(error_of(c).find("--particles"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.methods = {"pmm", "magic"};
  EXPECT_NE(error_of(c).find("magic"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.options = "no_such_key=1";
  const std::string option_error = error_of(c);
  EXPECT_NE(option_error.find("--options"), std::string::npos);
  EXPECT_NE(option_error.find("no_such_key"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.order = "hilbert";
  EXPECT_NE(error_of(c).find("--order"), std::string::npos);
  c = tiny_command(dir / "bench");
  c.options = "threads=4";
  EXPECT_NE(error_of(c).find("--threads"), std::string::npos);
}

TEST(Bench, ParticleOrdersAreTimedSideBySide) {
  test::TempDir dir;
  BenchCommand c = tiny_command(dir / "bench");
  c.chi = {2};
  c.methods = {"pmm", "exact"};
  c.particle_orders = {"input", "blocked"};
  c.repeats = 2;
  c.limits = false;
  const BenchOutcome out = run_bench(c);
  ASSERT_EQ(out.rows.size(), 4u);  // per method, one row per order
  for (std::size_t i = 0; i < out.rows.size(); ++i) {
    const BenchRow& r = out.rows[i];
    SCOPED_TRACE(r.method + " " + r.particle_order);
    EXPECT_EQ(r.method, i < 2 ? "pmm" : "exact");
    EXPECT_EQ(r.particle_order, i % 2 ? "blocked" : "input");
    EXPECT_NE(r.options.find("particle_order=" + r.particle_order), std::string::npos);
    EXPECT_EQ(r.ordered_blocks > 0, r.particle_order == "blocked");
    EXPECT_EQ(r.repeats, 2);
    EXPECT_GT(r.time_median_ms, 0);
    EXPECT_LT(r.volume_error, 1e-12);
  }
  // The same scene, the same sub-elements, in either order.
  EXPECT_EQ(out.rows[0].sub_elements, out.rows[1].sub_elements);
  EXPECT_NE(test::read_text(out.output / "bench.csv").find("particle_order"), std::string::npos);
  // --options may not set what --particle-order sets; alone it may.
  c.options = "particle_order=input";
  EXPECT_NE(error_of(c).find("--particle-order"), std::string::npos);
  c.particle_orders = {"sideways"};
  c.options.clear();
  EXPECT_NE(error_of(c).find("--particle-order"), std::string::npos);
  c.particle_orders.clear();
  c.options = "particle_order=blocked";
  const BenchOutcome alone = run_bench(c);
  ASSERT_EQ(alone.rows.size(), 2u);
  EXPECT_EQ(alone.rows[0].particle_order, "blocked");
}

TEST(BenchTiming, RoundsTakeEveryEngineInTurnAndRatiosArePaired) {
  std::vector<std::size_t> calls;
  const auto ms = time_rounds(3, 4, [&](std::size_t k) { calls.push_back(k); });
  EXPECT_EQ(calls, (std::vector<std::size_t>{0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}));
  ASSERT_EQ(ms.size(), 3u);
  for (const auto& m : ms) EXPECT_EQ(m.size(), 4u);
  // The ratio is taken within each round. Round 3 is slow for both engines (a busy
  // machine) and keeps its ratio, round 2 for one only: the median of the ratios (2, 0.5,
  // 2) is 2, where the ratio of the medians (10 / 20) would be 0.5.
  const std::vector<double> one = {10, 10, 40}, two = {5, 20, 20};
  EXPECT_EQ(round_ratio(one, two).median, 2.0);
  EXPECT_EQ(median(one) / median(two), 0.5);
  EXPECT_EQ(round_ratio({10, 30, 20}, {10, 10, 10}).median, 2.0);
  EXPECT_EQ(round_ratio({10, 20, 30}, {10, 5, 60}).median, 1.0);  // the ratios (1, 4, 0.5), not the medians (20 / 10)
  EXPECT_TRUE(std::isnan(round_ratio({}, {}).median));
  const RoundRatio spread = round_ratio({10, 20, 30}, {10, 5, 60});
  EXPECT_EQ(spread.min, 0.5);
  EXPECT_EQ(spread.max, 4.0);
  EXPECT_TRUE(std::isnan(round_ratio({}, {}).max));
}

TEST(Bench, ThreadCountsAreTimedSideBySideWithPairedSpeedups) {
  test::TempDir dir;
  BenchCommand c = tiny_command(dir / "bench");
  c.chi = {2};
  c.methods = {"direct", "pmm"};
  c.threads = {1, 2};
  c.repeats = 3;
  const BenchOutcome out = run_bench(c);
  ASSERT_EQ(out.rows.size(), 4u);  // per method, one row per thread count
  for (std::size_t i = 0; i < out.rows.size(); ++i) {
    const BenchRow& r = out.rows[i];
    SCOPED_TRACE(r.method + " " + std::to_string(r.threads));
    EXPECT_EQ(r.method, i < 2 ? "direct" : "pmm");
    EXPECT_EQ(r.threads, i % 2 ? 2 : 1);
    EXPECT_NE(r.options.find("threads=" + std::to_string(r.threads)), std::string::npos);
    EXPECT_LT(r.volume_error, 1e-12);
    EXPECT_LE(r.time_min_ms, r.time_median_ms);
    EXPECT_LE(r.time_median_ms, r.time_max_ms);
    if (r.threads == 1) {
      EXPECT_TRUE(std::isnan(r.speedup));
      EXPECT_TRUE(std::isnan(r.speedup_max));
      EXPECT_TRUE(std::isnan(r.control_speedup));
    } else {
      EXPECT_GT(r.speedup, 0);
      EXPECT_TRUE(std::isfinite(r.speedup));
      EXPECT_LE(r.speedup_min, r.speedup);
      EXPECT_LE(r.speedup, r.speedup_max);
      // The machine's control, timed in the same rounds.
      EXPECT_GT(r.control_speedup, 0);
      EXPECT_TRUE(std::isfinite(r.control_speedup));
    }
  }
  EXPECT_EQ(out.rows[0].sub_elements, out.rows[1].sub_elements);
  ASSERT_EQ(out.limits.size(), 2u);
  EXPECT_EQ(out.limits[0].threads, 1);
  EXPECT_EQ(out.limits[1].threads, 2);
  EXPECT_TRUE(std::isnan(out.limits[0].store_speedup));
  for (double s : {out.limits[1].bandwidth_speedup, out.limits[1].store_speedup, out.limits[1].scatter_speedup,
                   out.limits[1].locate_speedup}) {
    EXPECT_GT(s, 0);
    EXPECT_TRUE(std::isfinite(s));
  }
  for (const BenchRow& r : out.rows) EXPECT_EQ(r.store_ms, out.limits[r.threads - 1].store_ms);
  EXPECT_NE(test::read_text(out.output / "limits.csv").find("store_speedup"), std::string::npos);
  EXPECT_NE(test::read_text(out.output / "bench.csv").find("control_speedup"), std::string::npos);
  // Without a 1-thread count there is nothing to compare with.
  c.threads = {2};
  c.methods = {"direct"};
  const BenchOutcome two = run_bench(c);
  ASSERT_EQ(two.rows.size(), 1u);
  EXPECT_TRUE(std::isnan(two.rows[0].speedup));
  EXPECT_TRUE(std::isnan(two.rows[0].control_speedup));
  EXPECT_TRUE(std::isnan(two.limits[0].store_speedup));
  // Without the limits there is no control either; the speed-up stays.
  c.threads = {1, 2};
  c.limits = false;
  const BenchOutcome bare = run_bench(c);
  ASSERT_EQ(bare.rows.size(), 2u);
  EXPECT_TRUE(std::isfinite(bare.rows[1].speedup));
  EXPECT_TRUE(std::isnan(bare.rows[1].control_speedup));
}

// Every method's engines are timed in the same rounds as direct's: a row's ratio to direct
// is the median over the rounds of its time over direct's at the same thread count and
// particle order, so it lies within the bounds the two rows' least and greatest times give.
TEST(Bench, EachMethodsRatioToDirectIsTakenWithinTheRounds) {
  test::TempDir dir;
  BenchCommand c = tiny_command(dir / "bench");
  c.chi = {2};
  c.methods = {"pmm", "direct"};  // direct not first
  c.threads = {1, 2};
  c.particle_orders = {"input", "blocked"};
  c.repeats = 3;
  c.limits = false;
  const BenchOutcome out = run_bench(c);
  ASSERT_EQ(out.rows.size(), 8u);  // per method, thread count and order
  for (std::size_t i = 0; i < 4; ++i) {
    const BenchRow& pmm = out.rows[i];
    const BenchRow& direct = out.rows[4 + i];
    SCOPED_TRACE(std::to_string(pmm.threads) + " " + pmm.particle_order);
    ASSERT_EQ(pmm.method, "pmm");
    ASSERT_EQ(direct.method, "direct");
    ASSERT_EQ(pmm.threads, direct.threads);
    ASSERT_EQ(pmm.particle_order, direct.particle_order);
    EXPECT_EQ(direct.direct_ratio, 1.0);
    EXPECT_GE(pmm.direct_ratio, pmm.time_min_ms / direct.time_max_ms);
    EXPECT_LE(pmm.direct_ratio, pmm.time_max_ms / direct.time_min_ms);
  }
  EXPECT_NE(test::read_text(out.output / "bench.csv").find("direct_ratio"), std::string::npos);
  // Without direct there is no ratio.
  c.methods = {"pmm"};
  c.particle_orders = {};
  const BenchOutcome alone = run_bench(c);
  for (const BenchRow& r : alone.rows) EXPECT_TRUE(std::isnan(r.direct_ratio));
}

TEST(Bench, AllIsEveryEngineMethod) {
  test::TempDir dir;
  BenchCommand c = tiny_command(dir / "bench");
  c.particles = {300};
  c.chi = {2};
  c.methods = {"all"};
  c.limits = false;
  const BenchOutcome out = run_bench(c);
  // The engine's own list through its C API (vfe_method_name), independent of the bench.
  std::vector<std::string> names;
  for (std::int32_t i = 0; vfe_method_name(i); ++i) names.emplace_back(vfe_method_name(i));
  ASSERT_EQ(names.size(), 9u);  // direct, pmm, exact, divided, gaussian, porous_cube, big_particle, trilinear, auto
  ASSERT_EQ(out.rows.size(), names.size());
  for (std::size_t i = 0; i < names.size(); ++i) EXPECT_EQ(out.rows[i].method, names[i]);
}

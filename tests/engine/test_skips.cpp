// The switches that skip work a scene does not need (fast_path, rotation_bank,
// incremental, touched_only): each gives the field the full computation gives, and
// steady-state computes allocate nothing.
#include "particles.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <limits>
#include <new>
#include <random>

// Counts operator new calls in this test binary (the engine is linked into it), to check
// that steady-state computes reuse their scratch.
namespace {
std::atomic<std::int64_t> g_allocations{0};
}  // namespace

#pragma GCC diagnostic ignored "-Wmismatched-new-delete"  // new and delete both use malloc/free
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace vfe::test {
namespace {

/// A loose bed of spheres with diameters 0.8..1.2 in a 12 x 12 x 12 box.
Particles random_bed(std::uint32_t seed, int n) { return random_spheres(seed, n, 0.7, 11.3, 0.4, 0.6); }

/// Moves every k-th particle by a random step of up to `step` per axis.
void move_some(Particles& p, std::uint32_t seed, int k, double step) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-step, step);
  for (std::size_t i = 0; i < p.radii.size(); i += k)
    for (int d = 0; d < 3; ++d) p.centres[3 * i + d] += u(rng);
}

TEST(Skips, FastPathOffGivesTheSameFieldWithNoFastParticles) {
  const Particles p = random_bed(1, 400);
  for (const char* method : {"pmm", "exact", "divided", "porous_cube"}) {  // direct has no fast path
    Engine on(grid(2.0, 6, 6, 6)), off(grid(2.0, 6, 6, 6));
    const std::string opts = std::string("method=") + method + " particle_grid=200";
    const auto a = run(on, p, opts);
    const auto b = run(off, p, opts + " fast_path=0");
    EXPECT_GT(on.last_report().fast_path_particles, 0) << method;
    EXPECT_EQ(off.last_report().fast_path_particles, 0) << method;
    EXPECT_LT(l1(a, b), 1e-12 * p.volume()) << method;
  }
}

TEST(Skips, RotationBankOffUsesOtherRotationsOfTheSameQuality) {
  const Particles p = random_bed(2, 400);
  Engine e(grid(1.0, 12, 12, 12));
  const auto exact = run(e, p, "method=exact");
  const auto bank = run(e, p, "method=pmm particle_grid=100");
  const auto no_bank = run(e, p, "method=pmm particle_grid=100 rotation_bank=0");
  EXPECT_NEAR(total(no_bank), p.volume(), 1e-12 * p.volume());
  EXPECT_GT(l1(bank, no_bank), 1e-6 * p.volume());  // the switch changes the rotations
  const double e_bank = l1(bank, exact), e_no_bank = l1(no_bank, exact);
  EXPECT_LT(e_no_bank, 1.3 * e_bank);
  EXPECT_LT(e_bank, 1.3 * e_no_bank);
}

/// Runs frames through an incremental engine and a fresh full compute; both fields agree.
void expect_incremental_matches(const std::string& options) {
  Particles p = random_bed(3, 600);
  Engine inc(grid(1.5, 8, 8, 8)), full(grid(1.5, 8, 8, 8));
  inc.configure(options + " incremental=1");
  full.configure(options);
  std::vector<double> a(inc.cell_count()), b(full.cell_count());
  for (int frame = 0; frame < 6; ++frame) {
    if (frame > 0) move_some(p, 10 + frame, 7, 0.3);
    inc.compute(p.view(), a);
    full.compute(p.view(), b);
    const double moved = inc.last_report_value("moved_particles");
    EXPECT_EQ(moved, frame == 0 ? 600.0 : double((600 + 6) / 7)) << options << " frame " << frame;
    EXPECT_LT(l1(a, b), 1e-11 * p.volume()) << options << " frame " << frame;
    EXPECT_NEAR(inc.last_report().deposited_volume + inc.last_report().dropped_volume, p.volume(),
                1e-11 * p.volume());
  }
}

TEST(Skips, IncrementalEqualsFullComputeForEveryAccumulation) {
  for (const char* acc : {"accumulation=private", "accumulation=atomic", "deterministic=1"})
    for (const char* method : {"method=pmm particle_grid=300", "method=exact", "method=direct"})
      expect_incremental_matches(std::string(method) + " " + acc + " outside=drop");
}

TEST(Skips, IncrementalSkipsParticlesWithinTheTolerance) {
  Particles p = random_bed(4, 300);
  Engine e(grid(1.5, 8, 8, 8));
  e.configure("method=pmm particle_grid=100 incremental=1 move_tolerance=0.01");
  std::vector<double> first(e.cell_count()), second(e.cell_count());
  e.compute(p.view(), first);
  move_some(p, 5, 1, 0.009);  // every particle, each axis by less than the tolerance
  e.compute(p.view(), second);
  EXPECT_EQ(e.last_report_value("moved_particles"), 0.0);
  EXPECT_EQ(e.last_report().sub_elements, 0);
  EXPECT_EQ(first, second);
  move_some(p, 6, 1, 0.009);  // drifts add up against the last deposit's position: some move
  e.compute(p.view(), second);
  EXPECT_GT(e.last_report_value("moved_particles"), 0.0);
}

TEST(Skips, IncrementalHandlesGrowthConfigureAndFailures) {
  Particles p = random_bed(5, 500);
  Particles head;  // the first 300 particles: a bed that then grows to 500
  head.centres.assign(p.centres.begin(), p.centres.begin() + 900);
  head.radii.assign(p.radii.begin(), p.radii.begin() + 300);
  Engine e(grid(1.5, 8, 8, 8)), full(grid(1.5, 8, 8, 8));
  e.configure("method=exact incremental=1 outside=error");
  full.configure("method=exact outside=error");
  std::vector<double> a(e.cell_count()), b(e.cell_count());
  e.compute(head.view(), a);
  e.compute(p.view(), a);
  EXPECT_EQ(e.last_report_value("moved_particles"), 200.0);  // only the new ones
  full.compute(p.view(), b);
  EXPECT_LT(l1(a, b), 1e-11 * p.volume());

  // A moved particle outside the mesh fails the compute and changes nothing.
  Particles bad = p;
  bad.centres[0] = 100.0;
  std::vector<double> untouched(a.size(), -7.0);
  EXPECT_THROW(e.compute(bad.view(), untouched), Error);
  EXPECT_EQ(untouched, std::vector<double>(a.size(), -7.0));
  move_some(p, 8, 3, 0.2);
  e.compute(p.view(), a);
  full.compute(p.view(), b);
  EXPECT_LT(l1(a, b), 1e-11 * p.volume());

  e.configure("method=pmm particle_grid=50");  // any configure starts afresh
  e.compute(p.view(), a);
  EXPECT_EQ(e.last_report_value("moved_particles"), 500.0);
  e.compute(head.view(), a);  // fewer particles: afresh
  EXPECT_EQ(e.last_report_value("moved_particles"), 300.0);
  EXPECT_NEAR(total(a), head.volume(), 1e-12 * head.volume());
}

TEST(Skips, TouchedOnlyEqualsTheFullFieldAsParticlesMoveAway) {
  Particles p = random_bed(6, 200);
  Engine touched(grid(1.0, 12, 12, 12)), full(grid(1.0, 12, 12, 12));
  const std::string opts = "method=pmm particle_grid=150 outside=drop alpha_min=0.5";
  touched.configure(opts + " touched_only=1");
  full.configure(opts);
  std::vector<double> a(touched.cell_count()), b(full.cell_count());
  for (int frame = 0; frame < 4; ++frame) {
    // Shift everything by 2 cells a frame: the cells left behind must be cleared, and
    // particles leave through the top (dropped volume).
    for (std::size_t i = 0; i < p.radii.size(); ++i) p.centres[3 * i + 2] += frame == 0 ? 0.0 : 2.0;
    touched.compute(p.view(), a);
    full.compute(p.view(), b);
    EXPECT_LT(l1(a, b), 1e-12 * p.volume()) << frame;
    const Report& rt = touched.last_report();
    const Report& rf = full.last_report();
    EXPECT_NEAR(rt.deposited_volume, rf.deposited_volume, 1e-12 * p.volume());
    EXPECT_NEAR(rt.dropped_volume, rf.dropped_volume, 1e-12 * p.volume());
    EXPECT_NEAR(rt.clipped_volume, rf.clipped_volume, 1e-12 * p.volume());
    std::int64_t nonzero = 0;
    for (double x : b) nonzero += x != 0.0;
    EXPECT_EQ(touched.last_report_value("touched_cells"), double(nonzero));
    EXPECT_EQ(full.last_report_value("touched_cells"), -1.0);
  }
  EXPECT_GT(full.last_report().dropped_volume, 0.0);
}

TEST(Skips, UnknownReportKeyNamesTheKnownOnes) {
  Engine e(grid(1.0, 2, 2, 2));
  try {
    e.last_report_value("bogus");
    FAIL();
  } catch (const Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(err.what()).find("moved_particles"), std::string::npos);
  }
}

/// Checks that after a warm-up, computes on engines made by make_engine allocate nothing.
template <class MakeEngine>
void expect_no_allocation(const Particles& p, MakeEngine&& make_engine, std::initializer_list<const char*> options) {
  for (const char* opts : options) {
    for (const int threads : {1, 2}) {
      Engine e = make_engine();
      e.configure(std::string(opts) + " threads=" + std::to_string(threads));
      std::vector<double> out(e.cell_count());
      for (int i = 0; i < 3; ++i) e.compute(p.view(), out);  // warm-up: templates, scratch
      // With 2 threads a compute may still allocate the first time a thread takes part
      // (its scratch); one thread must never allocate again.
      std::int64_t fewest = std::numeric_limits<std::int64_t>::max(), most = 0;
      for (int i = 0; i < 4; ++i) {
        const std::int64_t before = g_allocations.load();
        e.compute(p.view(), out);
        const std::int64_t count = g_allocations.load() - before;
        fewest = std::min(fewest, count);
        most = std::max(most, count);
      }
      EXPECT_EQ(fewest, 0) << opts << " threads=" << threads;
      if (threads == 1) {
        EXPECT_EQ(most, 0) << opts;
      }
    }
  }
}

TEST(Skips, SteadyStateComputesAllocateNothing) {
  const Particles p = random_bed(7, 2000);
  expect_no_allocation(p, [] { return Engine(grid(1.0, 12, 12, 12)); },
                       {"method=pmm accumulation=private", "method=pmm accumulation=atomic",
                        "method=exact touched_only=1", "method=pmm incremental=1", "method=pmm deterministic=1",
                        "method=direct", "method=gaussian", "method=divided"});
  // direct's bins (85^3 cells, above the engine's 600000, two threads): a pool sized by the
  // particle count.
  const Particles many = random_spheres(8, 70000, 0.0, 21.0, 0.05, 0.2);
  Engine binned(grid(0.25, 85, 85, 85));
  run(binned, many, "method=direct threads=2");
  EXPECT_GT(binned.last_report_value("binned_regions"), 0.0);
  expect_no_allocation(many, [] { return Engine(grid(0.25, 85, 85, 85)); }, {"method=direct"});
  std::vector<double> nodes{0, 1, 2.5, 4, 5, 6, 7, 8, 9, 9.5, 10, 11, 12};
  expect_no_allocation(p, [&] { return Engine(RectilinearGridSpec{{nodes, nodes, nodes}}); },
                       {"method=pmm periodic=xz", "method=exact", "method=direct"});
  // The packed bed of a polyMesh box (spheres scaled into its 10 x 10 x 30 mm).
  Particles small = p;
  for (double& x : small.centres) x *= 1e-3 * 10.0 / 12.0;
  for (double& r : small.radii) r *= 1e-3 * 10.0 / 12.0;
  expect_no_allocation(small, [] { return Engine(PolyMeshSpec{VFE_SOURCE_DIR "/data/openfoam/box_uniform_10x10x30"}); },
                       {"method=pmm", "method=exact", "method=direct"});
}

}  // namespace
}  // namespace vfe::test

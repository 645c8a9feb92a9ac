// Every method on every mesh kind, the accumulator's strategies after a failure, and the
// one-engine-one-thread guard.
#include "particles.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <fenv.h>

#include <atomic>
#include <cmath>
#include <initializer_list>
#include <memory>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

namespace vfe::test {
namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

std::vector<double> uniform(double lo, double h, int n) {
  std::vector<double> x(static_cast<std::size_t>(n) + 1);
  for (int i = 0; i <= n; ++i) x[i] = lo + h * i;
  return x;
}

double max_abs_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

// A rectilinear grid with uniform nodes is the Cartesian grid: every method gives the same
// field (the rectilinear drivers locate by search and weigh in real coordinates, so only
// rounding differs), with the periodic axes too.
TEST(EveryMesh, UniformRectilinearGridEqualsCartesianForEveryMethod) {
  const double h = 1e-3;
  Engine cart(grid(h, 12, 10, 8));
  Engine rect(RectilinearGridSpec{{uniform(0, h, 12), uniform(0, h, 10), uniform(0, h, 8)}});
  const Particles p = random_spheres(7, 300, -0.5e-3, 10.5e-3, 0.2e-3, 1.3e-3);
  for (const char* periodic : {"none", "xz"}) {
    for (const std::string_view m : method_names()) {
      // auto weighs each path by the cost of its mesh kind: the grids may send a sphere
      // different ways (tests/engine/test_hybrid.cpp checks each path's result).
      if (m == "auto") continue;
      SCOPED_TRACE(std::string(m) + " periodic=" + periodic);
      const std::string opts = "method=" + std::string(m) + " periodic=" + periodic + " particle_grid=60";
      const std::vector<double> a = run(cart, p, opts), b = run(rect, p, opts);
      EXPECT_LT(max_abs_difference(a, b), 1e-9 * p.volume());
      EXPECT_NEAR(std::accumulate(b.begin(), b.end(), 0.0), p.volume(), 1e-12 * p.volume());
    }
  }
}

// On box_uniform (a polyMesh of 2 mm box cells) the point methods and big_particle give the
// Cartesian grid's fields: the same points land in the same cells (the polyMesh's tie rule
// is the grid's), and the same cell centres lie in each sphere.
TEST(EveryMesh, BoxPolyMeshEqualsCartesianForPointMethodsAndBigParticle) {
  Engine poly(PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
  Engine cart(grid(0.002, 10, 10, 30));
  Particles p = packed_bed(3000);
  for (const char* m : {"direct", "pmm", "divided", "big_particle", "exact"}) {
    SCOPED_TRACE(m);
    const std::string opts = std::string("method=") + m + " particle_grid=80 outside=centre";
    const std::vector<double> a = run(cart, p, opts), b = run(poly, p, opts + " lattice=0");  // general path
    EXPECT_LT(max_abs_difference(a, b), 1e-12 * p.volume());
  }
  // big_particle with particles larger than the cells: shares by the centres within.
  Particles big;
  big.add(0.01, 0.01, 0.03, 0.0035);
  big.add(0.004, 0.016, 0.01, 0.0027);
  const std::vector<double> a = run(cart, big, "method=big_particle"), b = run(poly, big, "method=big_particle lattice=0");
  EXPECT_LT(max_abs_difference(a, b), 1e-12 * big.volume());
  std::int64_t shared = 0;
  for (const double v : b) shared += v > 0;
  EXPECT_GT(shared, 20);  // many cells, not the own cell alone
}

// Every method that runs on a polyMesh conserves the volume of particles inside it, on the
// meshes that are not boxes too.
TEST(EveryMesh, PolyMeshMethodsConserveVolume) {
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    Engine e(PolyMeshSpec{kData + "openfoam/" + mesh});
    const Particles p = random_spheres(3, 200, 0.004, 0.016, 0.0003, 0.0012);
    for (const std::string_view m : method_names()) {
      SCOPED_TRACE(std::string(mesh) + " " + std::string(m));
      try {
        const std::vector<double> f = run(e, p, "method=" + std::string(m) + " outside=nearest particle_grid=40");
        EXPECT_NEAR(std::accumulate(f.begin(), f.end(), 0.0), p.volume(), 1e-12 * p.volume());
      } catch (const Error& err) {
        EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED) << err.what();
        EXPECT_EQ(m, "trilinear");  // the one method that needs a structured stencil
      }
    }
  }
}

/// Traps the floating-point exceptions OpenFOAM's solvers trap (FOAM_SIGFPE) while alive:
/// an invalid operation (a comparison with NaN, 0/0), a division by zero or an overflow in
/// the engine then ends the test with SIGFPE, as it ends the host's run.
struct HostFloatingPointTraps {
  static constexpr int kTraps = FE_INVALID | FE_DIVBYZERO | FE_OVERFLOW;
  HostFloatingPointTraps() : before(fegetexcept()) { feenableexcept(kTraps); }
  ~HostFloatingPointTraps() {
    fedisableexcept(kTraps);
    feenableexcept(before);
  }
  const int before;  ///< the traps that were on
};

// Every method on every mesh kind, and the coupling calls on its weights, run without
// raising a trapped exception, with spheres centred on cell faces, edges and corners, and in
// cut cells of the curved and snappy meshes. (The exact overlap on a polyMesh once signalled
// a declined face set with NaN and took its minimum: the OpenFOAM function object died with
// SIGFPE.) One thread, so the trapping thread does all the work.
TEST(EveryMesh, NoMethodRaisesAFloatingPointExceptionThatHostsTrap) {
  Particles on_grid;  // on the 2 mm grid's nodes, edges and faces, and off them
  for (int i = 1; i < 9; ++i)
    for (const double offset : {0.0, 0.5e-3, 1e-3, 1e-15})
      on_grid.add(0.002 * i + offset, 0.002 * (9 - i) + offset / 2, 0.004 * i + offset, 0.0004 + 0.0002 * (i % 4));
  const Particles random = random_spheres(19, 150, 0.003, 0.017, 0.0003, 0.0012);
  struct Case {
    std::string label;
    std::unique_ptr<Engine> engine;
    std::string options;
  };
  const HostFloatingPointTraps traps;  // engines are built under the traps too, as in a host
  std::vector<Case> cases;
  cases.push_back({"grid", std::make_unique<Engine>(grid(0.002, 10, 10, 30)), ""});
  cases.push_back({"grid periodic", std::make_unique<Engine>(grid(0.002, 10, 10, 30)), " periodic=xz"});
  cases.push_back({"rectilinear",
                   std::make_unique<Engine>(RectilinearGridSpec{
                       {uniform(0, 0.002, 10), uniform(0, 0.002, 10), {0, 0.001, 0.003, 0.006, 0.01, 0.03, 0.06}}}),
                   ""});
  for (const char* lattice : {"", " lattice=0"})
    cases.push_back({std::string("box_uniform") + lattice,
                     std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"}), lattice});
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle"})
    cases.push_back({mesh, std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/" + mesh}), ""});
  for (Case& c : cases) {
    for (const std::string_view m : method_names()) {
      for (const Particles* p : std::initializer_list<const Particles*>{&on_grid, &random}) {
        SCOPED_TRACE(c.label + " " + std::string(m) + (p == &random ? " random" : " on the grid"));
        try {
          const std::vector<double> f =
              run(*c.engine, *p, "method=" + std::string(m) + " outside=nearest threads=1 weights=1" + c.options);
          EXPECT_NEAR(std::accumulate(f.begin(), f.end(), 0.0), p->volume(), 1e-12 * p->volume());
          // The coupling calls on the same weights: a unit value per particle deposits n,
          // a unit field interpolates to 1 at every particle, the void fraction is finite.
          const std::size_t n = p->radii.size(), cells = f.size();
          std::vector<double> deposited(cells), interpolated(n), eps(cells);
          c.engine->deposit(1, std::vector<double>(n, 1.0), deposited);
          EXPECT_NEAR(std::accumulate(deposited.begin(), deposited.end(), 0.0), double(n), 1e-12 * n);
          c.engine->interpolate(1, std::vector<double>(cells, 1.0), interpolated);
          for (const double x : interpolated) ASSERT_NEAR(x, 1.0, 1e-12);
          c.engine->void_fraction(eps);
          for (const double x : eps) ASSERT_TRUE(std::isfinite(x));
        } catch (const Error& err) {
          EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED) << err.what();
          EXPECT_EQ(m, "trilinear") << err.what();  // the one method that needs a structured stencil
        }
      }
    }
  }
}

// A bad particle (a radius of 0, negative, NaN or whose cube overflows, a NaN or infinite
// centre)
// under a host's traps gives the error naming it, not a signal, with every method, on a
// first compute and after a good one (whose diameters pmm's fused pass then takes for its
// bank), with one and two threads, the particles ordered by the engine, the general loop.
// (The validation's four-lane pass took the minimum of a NaN radius, which raises the invalid
// operation; a pass that planned its spheres before checking them would divide by the zero
// radius.)
TEST(EveryMesh, BadParticlesGiveTheErrorNotATrappedExceptionThatHostsTrap) {
  const Particles good = random_spheres(12, 3000, 0.002, 0.018, 0.0003, 0.0008);
  const HostFloatingPointTraps traps;
  // The grid with every option; the box polyMesh (on its lattice of grid cells, and its own
  // paths with lattice=0) with fewer.
  for (const char* mesh : {"grid", "box_uniform", "box_uniform lattice=0"})
    for (const std::string_view m : method_names())
      for (const char* options : {" threads=1", " threads=2", " threads=2 particle_order=blocked",
                                  " threads=1 accumulation=atomic"})
        for (const bool after_good : {false, true})
          for (int kind = 0; kind < 6; ++kind) {
            const bool grid_case = std::string_view(mesh) == "grid";
            if (!grid_case && (m == "trilinear" || std::string_view(options) != " threads=2")) continue;
            SCOPED_TRACE(std::string(mesh) + " " + std::string(m) + options +
                         (after_good ? " after a good compute" : "") + " kind " + std::to_string(kind));
            const std::unique_ptr<Engine> engine =
                grid_case ? std::make_unique<Engine>(grid(0.002, 10, 10, 10))
                          : std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
            Engine& e = *engine;
            if (!grid_case) e.configure(std::string_view(mesh).ends_with("lattice=0") ? "lattice=0" : "lattice=1");
            e.configure("method=" + std::string(m) + " outside=nearest" + options);
            std::vector<double> out(e.cell_count(), 7.0);
            if (after_good) e.compute(good.view(), out);
            Particles bad = good;
            const std::size_t at = 1234;
            switch (kind) {
              case 0: bad.radii[at] = 0.0; break;
              case 1: bad.radii[at] = -0.0005; break;
              case 2: bad.radii[at] = std::numeric_limits<double>::quiet_NaN(); break;
              case 3: bad.radii[at] = 1e200; break;  // its cube overflows
              case 4: bad.centres[3 * at] = std::numeric_limits<double>::quiet_NaN(); break;
              default: bad.centres[3 * at + 1] = std::numeric_limits<double>::infinity(); break;
            }
            std::fill(out.begin(), out.end(), 7.0);
            expect_compute_fails(e, bad, out, VFE_ERROR_INVALID_ARGUMENT, "particle 1234");
            EXPECT_EQ(out[0], 7.0);
          }
}

// A compute that fails part-way (one particle in the middle spans more cells than allowed)
// leaves nothing behind under any strategy: the next compute equals a fresh engine's.
TEST(EveryMesh, FailedComputeLeavesNothingBehindWithEveryStrategy) {
  const Particles good = random_spheres(11, 3000, 0.0, 0.02, 0.0003, 0.0006);
  Particles bad = good;
  bad.radii[1500] = 1.0;  // on periodic axes 1000 cells of 2 mm across each way: over the 2^26 limit
  for (const char* strategy : {"accumulation=private", "accumulation=atomic", "deterministic=1", "touched_only=1",
                               "incremental=1", "weights=1", "accumulation=atomic weights=1"}) {
    SCOPED_TRACE(strategy);
    const std::string opts = std::string("method=pmm particle_grid=20 threads=2 periodic=xyz ") + strategy;
    Engine fresh(grid(0.002, 10, 10, 10));
    const std::vector<double> expected = run(fresh, good, opts);
    Engine e(grid(0.002, 10, 10, 10));
    (void)run(e, good, opts);
    std::vector<double> out(e.cell_count(), 7.0);
    expect_compute_fails(e, bad, out, VFE_ERROR_INVALID_ARGUMENT, "particle 1500");
    EXPECT_EQ(out[0], 7.0);  // untouched
    const std::vector<double> after = run(e, good, opts);
    EXPECT_LT(max_abs_difference(after, expected), 1e-15 * good.volume());
    EXPECT_NEAR(std::accumulate(after.begin(), after.end(), 0.0), good.volume(), 1e-12 * good.volume());
  }
}

// Skips that cannot combine with a strategy are refused by configure, naming both.
TEST(EveryMesh, StrategiesThatCannotCombineAreRefused) {
  Engine e(grid(1, 4, 4, 4));
  for (const char* opts : {"touched_only=1 incremental=1", "touched_only=1 accumulation=atomic",
                           "deterministic=1 accumulation=private", "method=pmm method=exact"}) {
    SCOPED_TRACE(opts);
    try {
      e.configure(opts);
      FAIL();
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
    }
  }
  EXPECT_EQ(e.option("accumulation"), "auto");
  e.configure("incremental=1 accumulation=atomic");  // these combine
  e.configure("incremental=0 accumulation=auto touched_only=1 deterministic=1");
}

// Radii whose volume doubles cannot hold are refused with a message (they gave inf/NaN).
TEST(EveryMesh, VolumesThatOverflowAreRefused) {
  Engine e(grid(1, 4, 4, 4));
  for (const double r : {1e103, 1e-120}) {
    Particles p;
    p.add(2, 2, 2, r);
    std::vector<double> out(e.cell_count(), 3.0);
    try {
      e.compute(p.view(), out);
      FAIL() << r;
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_NE(std::string(err.what()).find("volume"), std::string::npos) << err.what();
    }
    EXPECT_EQ(out[0], 3.0);
  }
}

// One engine called from two threads at once: a call that finds it busy is refused, and
// every call that succeeds returns the right total (before the guard, 76 of 400 did not).
TEST(EveryMesh, TwoThreadsOnOneEngineAreRefusedNotCorrupted) {
  Engine e(grid(0.001, 20, 20, 20));
  e.configure("method=pmm particle_grid=40 threads=1");
  const Particles p = random_spheres(5, 4000, 0.0, 0.02, 0.0002, 0.0005);
  std::atomic<int> ok{0}, refused{0}, wrong{0};
  auto work = [&] {
    std::vector<double> out(e.cell_count());
    for (int i = 0; i < 40; ++i) {
      try {
        e.compute(p.view(), out);
        ++ok;
        if (std::abs(std::accumulate(out.begin(), out.end(), 0.0) - p.volume()) > 1e-12 * p.volume()) ++wrong;
      } catch (const Error& err) {
        ++refused;
        EXPECT_NE(std::string(err.what()).find("another thread"), std::string::npos) << err.what();
      }
    }
  };
  std::thread a(work), b(work);
  a.join();
  b.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(ok + refused, 80);
  EXPECT_GT(ok.load(), 0);
}

}  // namespace
}  // namespace vfe::test

namespace vfe::test {
namespace {

// outside=error takes a tolerance for DEM wall contacts: the shipped bed has spheres that
// overlap the box's walls by micrometres; they are refused without a tolerance, accepted
// with 20 um (their volume goes to the nearest cells), and a sphere 1 mm out still fails.
TEST(EveryMesh, OutsideErrorToleratesWallContacts) {
  Particles bed = packed_bed(20000);
  for (const char* mesh : {"grid", "polymesh"}) {
    SCOPED_TRACE(mesh);
    std::unique_ptr<Engine> e = std::string(mesh) == "grid"
                                    ? std::make_unique<Engine>(grid(0.002, 10, 10, 30))
                                    : std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
    std::vector<double> out(e->cell_count());
    e->configure("method=exact outside=error");
    EXPECT_THROW(e->compute(bed.view(), out), Error);
    e->configure("outside_tolerance=2e-5");
    e->compute(bed.view(), out);
    EXPECT_NEAR(std::accumulate(out.begin(), out.end(), 0.0), bed.volume(), 1e-12 * bed.volume());
    Particles far = bed;
    far.centres[2] = -0.001;  // particle 0 one millimetre below the bottom
    try {
      e->compute(far.view(), out);
      FAIL();
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_OUT_OF_DOMAIN);
      EXPECT_NE(std::string(err.what()).find("particle 0 "), std::string::npos) << err.what();
    }
  }
}

// Cells holding more solid than their volume are counted and their excess reported.
TEST(EveryMesh, OverfullCellsAreReported) {
  Engine e(grid(0.001, 4, 4, 4));
  Particles p;
  p.add(0.0015, 0.0015, 0.0015, 0.0009);  // a sphere larger than its 1 mm cell
  (void)run(e, p, "method=direct");
  EXPECT_EQ(e.last_report_value("overfull_cells"), 1.0);
  EXPECT_NEAR(e.last_report_value("overfull_volume"), p.volume() - 1e-9, 1e-21);
  (void)run(e, p, "method=exact");
  EXPECT_EQ(e.last_report_value("overfull_cells"), 0.0);
  EXPECT_EQ(e.last_report_value("overfull_volume"), 0.0);
}

// With incremental=1 the outside count covers every particle, moved or kept.
TEST(EveryMesh, IncrementalCountsOutsideParticlesLikeAFullCompute) {
  Particles bed = packed_bed(5000);
  Engine full(grid(0.002, 10, 10, 30)), inc(grid(0.002, 10, 10, 30));
  full.configure("method=exact outside=drop");
  inc.configure("method=exact outside=drop incremental=1");
  std::vector<double> a(full.cell_count()), b(inc.cell_count());
  for (int frame = 0; frame < 3; ++frame) {
    bed.centres[3 * frame + 2] += 1e-4;  // one particle moves per frame
    full.compute(bed.view(), a);
    inc.compute(bed.view(), b);
    EXPECT_GT(full.last_report().outside_particles, 0);
    EXPECT_EQ(inc.last_report().outside_particles, full.last_report().outside_particles);
    EXPECT_NEAR(inc.last_report().dropped_volume, full.last_report().dropped_volume, 1e-15);
  }
}

}  // namespace
}  // namespace vfe::test

namespace vfe::test {
namespace {

// On a grid "outside" means the same for every method: the spheres that reach beyond the box
// (the shipped bed's wall contacts), not whichever of their sub-elements or kernel tails did.
TEST(EveryMesh, OutsideCountIsTheSameForEveryMethodOnAGrid) {
  const Particles bed = packed_bed(20000);
  std::int64_t expected = 0;
  for (std::size_t i = 0; i < bed.radii.size(); ++i) {
    bool out = false;
    const double hi[3] = {0.02, 0.02, 0.06};
    for (int d = 0; d < 3; ++d)
      out |= bed.centres[3 * i + d] - bed.radii[i] < 0 || bed.centres[3 * i + d] + bed.radii[i] > hi[d];
    expected += out;
  }
  ASSERT_GT(expected, 1000);
  Engine e(grid(0.002, 10, 10, 30));
  for (const std::string_view m : method_names()) {
    (void)run(e, bed, "method=" + std::string(m) + " particle_grid=20");
    EXPECT_EQ(e.last_report().outside_particles, expected) << m;
  }
  (void)run(e, bed, "method=exact outside_tolerance=1e-4");
  EXPECT_EQ(e.last_report().outside_particles, 0);
}

}  // namespace
}  // namespace vfe::test

namespace vfe::test {
namespace {

// Legal inputs that would cost without bound are refused up front, naming the limit: a
// big_particle of 1000 cells' radius, exact and gaussian wrapping a periodic grid.
TEST(EveryMesh, UnboundedFootprintsAreRefusedQuickly) {
  Engine e(grid(1, 10, 10, 10));
  Particles p;
  p.add(5, 5, 5, 1000);
  std::vector<double> out(e.cell_count(), 3.0);
  for (const char* opts : {"method=big_particle", "method=exact periodic=xyz", "method=gaussian periodic=xyz",
                           "method=porous_cube periodic=xyz", "method=pmm particle_grid=20 periodic=xyz"}) {
    SCOPED_TRACE(opts);
    e.configure(std::string(opts) + (std::string(opts).find("periodic") ? "" : ""));
    expect_compute_fails(e, p, out, VFE_ERROR_INVALID_ARGUMENT, "2^26");
    EXPECT_EQ(out[0], 3.0);
    e.configure("periodic=none");
  }
}

}  // namespace
}  // namespace vfe::test

// Engine on Cartesian grids: conservation, agreement with brute force, determinism,
// outside policies, bad input.
#include <vfe/engine.hpp>

#include "particles.hpp"
#include <vfe/measures.hpp>
#include <vfe/stability.hpp>

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include <Eigen/Geometry>
#include <numbers>
#include <random>
#include <vector>

using vfe::CartesianGridSpec;
using vfe::Engine;
using vfe::ParticleView;
using vfe::test::grid;
using vfe::test::Particles;
using vfe::test::run;
using vfe::test::total;

namespace {

/// n spheres of radius in [rmin, rmax] wholly inside [0, L]^3 (fixed seed).
Particles random_particles(int n, double L, double rmin, double rmax, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ur(rmin, rmax), u01(0, 1);
  Particles p;
  for (int i = 0; i < n; ++i) {
    const double r = ur(rng);
    p.radii.push_back(r);
    for (int d = 0; d < 3; ++d) p.centres.push_back(r + (L - 2 * r) * u01(rng));
  }
  return p;
}

}  // namespace

TEST(Engine, EveryMethodConservesVolume) {
  Engine e(grid(1.0, 8, 8, 8));
  const Particles p = random_particles(300, 8.0, 0.2, 0.9, 1);
  for (const char* m : {"method=direct", "method=pmm", "method=pmm particle_grid=500 template=fibonacci",
                        "method=pmm orientation=none", "method=exact"}) {
    const auto f = run(e, p, m);
    EXPECT_NEAR(total(f), p.volume(), 1e-12 * p.volume()) << m;
    EXPECT_NEAR(e.last_report().particle_volume, p.volume(), 1e-12 * p.volume());
    EXPECT_EQ(e.last_report().outside_particles, 0);
  }
}

TEST(Engine, ExactMatchesBruteForceOverlapPerCell) {
  // Brute force: sphere_box_overlap over every cell of the grid, no fast path, no patch.
  const double h = 0.7;
  Engine e(grid(h, 6, 5, 7));
  const Particles p = random_particles(40, 3.5, 0.1, 1.2, 2);
  const auto f = run(e, p, "method=exact");
  std::vector<double> ref(f.size(), 0.0);
  for (std::size_t q = 0; q < p.radii.size(); ++q) {
    const Eigen::Vector3d c(p.centres[3 * q], p.centres[3 * q + 1], p.centres[3 * q + 2]);
    for (int k = 0; k < 7; ++k)
      for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 6; ++i)
          ref[i + 6 * (j + 5 * k)] += vfe::kernels::sphere_box_overlap(
              c, p.radii[q], Eigen::Vector3d(i * h, j * h, k * h), Eigen::Vector3d((i + 1) * h, (j + 1) * h, (k + 1) * h));
  }
  for (std::size_t c = 0; c < f.size(); ++c) EXPECT_NEAR(f[c], ref[c], 1e-13 * p.volume()) << "cell " << c;
}

TEST(Engine, ExactSplitsASphereCentredOnANodeIntoEighths) {
  Engine e(grid(1.0, 2, 2, 2));
  Particles p;
  p.centres = {1.0, 1.0, 1.0};
  p.radii = {0.5};
  const auto f = run(e, p, "method=exact");
  for (double x : f) EXPECT_NEAR(x, p.volume() / 8, 1e-15);
}

TEST(Engine, FastPathForAParticleInsideOneCell) {
  Engine e(grid(1.0, 3, 3, 3));
  Particles p;
  p.centres = {1.5, 1.5, 1.5};
  p.radii = {0.3};
  for (const char* m : {"method=pmm", "method=exact"}) {
    const auto f = run(e, p, m);
    EXPECT_EQ(e.last_report().fast_path_particles, 1) << m;
    EXPECT_DOUBLE_EQ(f[13], p.volume()) << m;
    EXPECT_DOUBLE_EQ(total(f), p.volume()) << m;
  }
}

TEST(Engine, DirectEqualsPmmWithOneSubElement) {
  Engine e(grid(0.5, 10, 10, 10));
  const Particles p = random_particles(500, 5.0, 0.1, 0.6, 3);
  const auto direct = run(e, p, "method=direct deterministic=1");
  const auto pmm = run(e, p, "method=pmm particle_grid=1 deterministic=1");
  for (std::size_t c = 0; c < direct.size(); ++c) EXPECT_NEAR(direct[c], pmm[c], 1e-15 * p.volume()) << c;
}

TEST(Engine, PmmConvergesToExactAsTheParticleGridGrows) {
  // L1 error (docs/design.md section 8) against the exact overlap falls as a power of n.
  Engine e(grid(1.0, 12, 12, 12));
  const Particles p = random_particles(400, 12.0, 0.5, 0.5, 4);  // chi = 1
  const auto exact = run(e, p, "method=exact");
  std::vector<double> vc(exact.size(), 1.0);
  std::vector<double> ns, errs;
  for (int n : {16, 64, 256, 1024, 4096}) {
    const auto f = run(e, p, "method=pmm template=fibonacci particle_grid=" + std::to_string(n));
    const auto m = vfe::compare_fields(f, exact, vc, p.volume());
    ns.push_back(std::log(n));
    errs.push_back(std::log(m.l1));
    EXPECT_LT(m.volume_error, 1e-12);
  }
  // Least-squares slope of log L1 against log n.
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < ns.size(); ++i) mx += ns[i] / ns.size(), my += errs[i] / ns.size();
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < ns.size(); ++i) sxy += (ns[i] - mx) * (errs[i] - my), sxx += (ns[i] - mx) * (ns[i] - mx);
  const double slope = sxy / sxx;
  RecordProperty("l1_slope", std::to_string(slope));
  std::printf("PMM L1 error: slope %.3f of log L1 against log n (first %.3g, last %.3g)\n", slope,
              std::exp(errs.front()), std::exp(errs.back()));
  EXPECT_LT(slope, -0.4);
  EXPECT_GT(slope, -0.9);
  for (std::size_t i = 1; i < errs.size(); ++i) EXPECT_LT(errs[i], errs[i - 1]);
}

TEST(Engine, DeterministicIsBitwiseIdenticalForOneAndTwoThreads) {
  Engine e(grid(0.4, 20, 20, 20));
  const Particles p = random_particles(2000, 8.0, 0.1, 0.5, 5);
  for (const char* m : {"method=pmm", "method=exact", "method=direct"}) {
    const auto one = run(e, p, std::string(m) + " deterministic=1 threads=1");
    const auto two = run(e, p, std::string(m) + " deterministic=1 threads=2");
    EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(double))) << m;
  }
}

TEST(Engine, AccumulationStrategiesAgree) {
  Engine e(grid(0.5, 16, 16, 16));
  const Particles p = random_particles(1500, 8.0, 0.1, 0.6, 6);
  const auto ref = run(e, p, "method=pmm accumulation=sorted threads=2");
  for (const char* a : {"accumulation=private", "accumulation=atomic", "accumulation=auto"}) {
    const auto f = run(e, p, std::string("method=pmm threads=2 ") + a);
    for (std::size_t c = 0; c < f.size(); ++c) ASSERT_NEAR(f[c], ref[c], 1e-14 * p.volume()) << a << " cell " << c;
  }
}

TEST(Engine, GivenOrientationsAreApplied) {
  // Turning the whole scene by 90 degrees about z (a symmetry of the grid) must turn the
  // field: particle at c with orientation q ~ particle at R c with orientation R q. The
  // fibonacci template has no symmetry, so ignoring q would break this.
  const int n = 4;
  Engine e(grid(1.0, n, n, 2));
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.8, 3.2), uz(0.6, 1.4), uq(-1, 1);
  Particles a, b;
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()));
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d c(u(rng), u(rng), uz(rng));
    const Eigen::Quaterniond q = Eigen::Quaterniond(uq(rng), uq(rng), uq(rng), uq(rng)).normalized();
    const Eigen::Vector3d mid(n / 2.0, n / 2.0, 0);
    const Eigen::Vector3d rc = mid + turn * (c - mid);
    const Eigen::Quaterniond rq = turn * q;
    a.radii.push_back(0.55);
    b.radii.push_back(0.55);
    a.centres.insert(a.centres.end(), {c[0], c[1], c[2]});
    b.centres.insert(b.centres.end(), {rc[0], rc[1], rc[2]});
    a.quats.insert(a.quats.end(), {q.w(), q.x(), q.y(), q.z()});
    b.quats.insert(b.quats.end(), {rq.w(), rq.x(), rq.y(), rq.z()});
  }
  const std::string opts = "method=pmm template=fibonacci particle_grid=50 orientation=given deterministic=1";
  const auto fa = run(e, a, opts);
  const auto fb = run(e, b, opts);
  const auto fa_unrotated = run(e, a, "method=pmm template=fibonacci particle_grid=50 orientation=none");
  double differs = 0;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        // (i, j) turns to (n-1-j, i).
        const int from = i + n * (j + n * k), to = (n - 1 - j) + n * (i + n * k);
        EXPECT_NEAR(fb[to], fa[from], 1e-12) << "cell " << from;
        differs += std::abs(fa[from] - fa_unrotated[from]);
      }
  EXPECT_GT(differs, 0.05 * a.volume());  // the orientations changed the field
}

TEST(Engine, OutsidePolicies) {
  Engine e(grid(1.0, 4, 4, 4));
  Particles p;
  p.centres = {0.1, 2.0, 2.0, 2.0, 2.0, 2.0};  // the first pokes out through x = 0
  p.radii = {0.4, 0.3};
  for (const char* m : {"method=direct", "method=pmm", "method=exact"}) {
    for (const char* o : {"outside=nearest", "outside=centre"}) {
      const auto f = run(e, p, std::string(m) + " " + o);
      EXPECT_NEAR(total(f), p.volume(), 1e-13) << m << o;
      EXPECT_EQ(e.last_report().dropped_volume, 0.0);
    }
  }
  // Drop: the exact method loses exactly the cap beyond x = 0 (height 0.3).
  const auto f = run(e, p, "method=exact outside=drop");
  const double h = 0.3, r = 0.4, cap = std::numbers::pi * h * h * (3 * r - h) / 3;
  EXPECT_NEAR(e.last_report().dropped_volume, cap, 1e-14);
  EXPECT_NEAR(total(f) + e.last_report().dropped_volume, p.volume(), 1e-14);
  EXPECT_EQ(e.last_report().outside_particles, 1);
  const auto g = run(e, p, "method=pmm outside=drop particle_grid=1000");
  EXPECT_NEAR(total(g) + e.last_report().dropped_volume, p.volume(), 1e-14);
  EXPECT_NEAR(e.last_report().dropped_volume, cap, 0.2 * cap);
  // Error: a clear message, the output untouched, the engine still usable.
  e.configure("method=exact outside=error");
  std::vector<double> out(e.cell_count(), 42.0);
  try {
    e.compute(p.view(), out);
    FAIL() << "expected an out-of-domain error";
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_OUT_OF_DOMAIN);
    EXPECT_NE(std::string(err.what()).find("particle 0"), std::string::npos) << err.what();
  }
  for (double x : out) EXPECT_EQ(x, 42.0);
  Particles inside;
  inside.centres = {2.0, 2.0, 2.0};
  inside.radii = {0.3};
  e.compute(inside.view(), out);
  EXPECT_NEAR(total(out), inside.volume(), 1e-15);
}

TEST(Engine, BadInputsGiveClearErrorsAndLeaveTheEngineUsable) {
  Engine e(grid(1.0, 4, 4, 4));
  Particles p = random_particles(10, 4.0, 0.2, 0.4, 7);
  std::vector<double> out(e.cell_count(), 7.0);
  auto expect_error = [&](const Particles& q, vfe_status status, const std::string& words) {
    try {
      e.compute(q.view(), out);
      ADD_FAILURE() << "expected an error containing '" << words << "'";
    } catch (const vfe::Error& err) {
      EXPECT_EQ(err.status(), status);
      EXPECT_NE(std::string(err.what()).find(words), std::string::npos) << err.what();
    }
    for (double x : out) ASSERT_EQ(x, 7.0);
  };
  Particles nan = p;
  nan.centres[3 * 3 + 1] = std::nan("");
  expect_error(nan, VFE_ERROR_INVALID_ARGUMENT, "particle 3");
  Particles neg = p;
  neg.radii[5] = -1;
  expect_error(neg, VFE_ERROR_INVALID_ARGUMENT, "particle 5: radius");
  Particles zero = p;
  zero.radii[2] = 0;
  expect_error(zero, VFE_ERROR_INVALID_ARGUMENT, "particle 2: radius");
  e.configure("orientation=given");
  expect_error(p, VFE_ERROR_INVALID_ARGUMENT, "orientation=given");
  e.configure("orientation=random");

  EXPECT_THROW(e.configure("methd=pmm"), vfe::Error);
  try {
    e.configure("method=pmm particle_grid=-3");
  } catch (const vfe::Error& err) {
    EXPECT_NE(std::string(err.what()).find("particle_grid"), std::string::npos);
  }
  EXPECT_EQ(e.option("method"), "pmm");  // all or nothing
  try {
    e.configure("periodic=xw");
    ADD_FAILURE() << "periodic=xw was accepted";
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(err.what()).find("periodic"), std::string::npos) << err.what();
  }
  EXPECT_THROW(Engine(grid(1.0, 0, 4, 4)), vfe::Error);
  EXPECT_THROW(Engine(grid(-1.0, 4, 4, 4)), vfe::Error);
  std::vector<double> short_out(3);
  EXPECT_THROW(e.compute(p.view(), short_out), vfe::Error);
  e.compute(p.view(), out);
  EXPECT_NEAR(total(out), p.volume(), 1e-13);
}

TEST(Engine, VoidFractionAndAlphaMinClipReportsTheClippedVolume) {
  Engine e(grid(1.0, 2, 1, 1));
  Particles p;
  p.centres = {0.5, 0.5, 0.5, 1.5, 0.5, 0.5, 1.5, 0.5, 0.5, 1.5, 0.5, 0.5};
  p.radii = {0.49, 0.49, 0.49, 0.49};  // three spheres in cell 1: more solid than it holds
  run(e, p, "method=exact");
  const double vs = 4.0 / 3.0 * std::numbers::pi * 0.49 * 0.49 * 0.49;
  std::vector<double> eps(2);
  e.void_fraction(eps);
  EXPECT_NEAR(eps[0], 1 - vs, 1e-15);
  EXPECT_NEAR(eps[1], 1 - 3 * vs, 1e-15);  // negative: no clip unless asked
  EXPECT_LT(eps[1], 0.0);
  EXPECT_EQ(e.last_report().clipped_volume, 0.0);
  run(e, p, "method=exact alpha_min=0.6");
  EXPECT_NEAR(e.last_report().clipped_volume, (vs - 0.4) + (3 * vs - 0.4), 1e-15);
  e.void_fraction(eps);
  EXPECT_EQ(eps[0], 0.6);
  EXPECT_EQ(eps[1], 0.6);
}

TEST(Engine, AutoParticleGridFollowsTheFittedStabilityFormula) {
  // n = 5 n_min(chi) (docs/stability.md), rounded up to the template ladder; more
  // sub-elements as chi falls; the flux form when the host gives U_s and dt_f.
  Engine e(grid(2.0, 4, 4, 4));
  std::int64_t previous = 0;
  for (double chi : {4.0, 3.0, 2.0, 1.5, 1.0, 0.75}) {
    const std::int64_t n = e.particle_grid_for(1.0, chi);
    const std::int64_t formula = vfe::auto_particle_grid(chi, "fibonacci");
    EXPECT_GE(n, formula) << chi;
    EXPECT_LE(double(n), 1.06 * double(formula) + 5) << chi;
    EXPECT_GE(n, previous) << chi;
    previous = n;
  }
  // Capped at particle_grid_max (20000 by default; the formula asks ~35000 at chi = 0.5).
  EXPECT_LE(e.particle_grid_for(1.0, 0.5), 20000);
  EXPECT_GT(e.particle_grid_for(1.0, 0.5), 19000);
  e.configure("particle_grid_max=100");
  EXPECT_LE(e.particle_grid_for(1.0, 1.0), 100);
  e.configure("particle_grid_max=20000");
  // A looser flux criterion (U_s dt_f / dx larger than pi/162) needs fewer sub-elements.
  const std::int64_t strict = e.particle_grid_for(1.0, 1.0);
  e.configure("superficial_velocity=1 fluid_dt=0.1");  // allows a jump of 0.1 per step at dx = 1
  EXPECT_LT(e.particle_grid_for(1.0, 1.0), strict);
  EXPECT_GE(e.particle_grid_for(1.0, 1.0),
            vfe::auto_particle_grid(1.0, "fibonacci", vfe::flux_jump_criterion(1, 0.1, 1.0)));
}

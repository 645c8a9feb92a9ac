// Stability stress test (docs/design.md section 8): the jump bound of the default template, the
// effect of template rotation, auto's stability between the sweep's chi values, and the
// direct method's threshold at chi = 3.
#include <vfe/engine.hpp>
#include <vfe/stability.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

namespace {

vfe::StabilityOptions options(double chi, const std::string& method, int trajectories) {
  vfe::StabilityOptions o;
  o.chi = chi;
  o.method = method;
  o.trajectories = trajectories;
  o.seed = 7;
  return o;
}

/// The engine's default template family.
std::string default_template() {
  vfe::Engine probe(vfe::CartesianGridSpec{});
  return probe.option("template");
}

}  // namespace

// One sub-element crossing a face changes eps by pi/(6 n chi^3). With the default
// (rotated) template at small n*s/d the sub-elements cross one by one: J reaches one
// sub-element, and at most two when two centroids happen to project within one step of
// each other (a pair, never a ring or a layer).
TEST(Stability, JumpBoundHoldsForTheDefaultTemplate) {
  for (double chi : {1.0, 1.5, 2.0}) {
    auto o = options(chi, "pmm", 16);
    o.particle_grids = {"4", "8", "12"};
    const auto rep = vfe::stability_test(o);
    for (const auto& r : rep.results) {
      SCOPED_TRACE("chi=" + std::to_string(chi) + " particle_grid=" + r.particle_grid);
      const double unit = vfe::sub_element_jump(double(r.grid_max), chi);
      EXPECT_GE(r.excess_in_sub_elements, 0.95);   // it does jump by a sub-element
      EXPECT_LE(r.excess_in_sub_elements, 2.0 + 1e-6);
      EXPECT_LE(r.max_jump, 2.0 * unit + r.max_jump_exact + 1e-12);
    }
  }
  // With a fine step, sub-elements cross one at a time: J is one sub-element. (Two of the
  // 8 centroids projecting within one step of each other onto a face normal is a chance of
  // about 28 pairs x 3 axes x step / d per trajectory, so the step is kept very fine.)
  auto o = options(1.5, "pmm", 8);
  o.particle_grids = {"8"};
  o.step = 1.0 / 20000.0;
  const auto r = vfe::stability_test(o).results.at(0);
  EXPECT_NEAR(r.excess_in_sub_elements, 1.0, 0.02);
}

// Unrotated structured templates let whole rings of centroids (equal z) cross a face in
// the same step; the rotated template does not.
TEST(Stability, UnrotatedSphericalTemplateCrossesWholeRings) {
  auto o = options(1.5, "pmm", 8);
  o.particle_grids = {"20"};
  o.engine_options = "template=spherical orientation=none";
  const auto none = vfe::stability_test(o).results.at(0);
  o.engine_options = "template=spherical orientation=random";
  const auto rotated = vfe::stability_test(o).results.at(0);
  EXPECT_GE(none.excess_in_sub_elements, 4.0 - 1e-6);
  EXPECT_LE(rotated.excess_in_sub_elements, 2.0 + 1e-6);
  EXPECT_GT(none.excess_jump, 1.9 * rotated.excess_jump);
}

// The formula's particle grid (5 n_min(chi)) is stable at chi values between the sweep's
// points, for the default template.
TEST(Stability, FormulaParticleGridIsStableBetweenSweepPoints) {
  const std::string family = default_template();
  for (double chi : {0.8, 1.1, 1.75, 2.2, 2.8}) {
    auto o = options(chi, "pmm", 16);
    o.particle_grids = {std::to_string(vfe::auto_particle_grid(chi, family))};
    const auto r = vfe::stability_test(o).results.at(0);
    SCOPED_TRACE("chi=" + std::to_string(chi) + " n=" + std::to_string(r.grid_max));
    EXPECT_TRUE(r.stable) << "J = " << r.excess_jump << " > " << vfe::kDefaultJumpCriterion;
  }
}

// particle_grid=auto is stable at chi values between the sweep's points.
TEST(Stability, AutoIsStableBetweenSweepPoints) {
  const std::string family = default_template();
  for (double chi : {0.8, 1.1, 1.75, 2.2, 2.8}) {
    vfe::Engine probe(vfe::CartesianGridSpec{});
    const std::int64_t n_auto = probe.particle_grid_for(1.0, chi);
    probe.configure("particle_grid=" + std::to_string(vfe::auto_particle_grid(chi, family)));
    const std::int64_t n_formula = probe.particle_grid_for(1.0, chi);
    // auto rounds 5 n_min(chi) up to its template ladder (5 % rungs above 100).
    EXPECT_GE(n_auto, n_formula) << "chi=" << chi;
    EXPECT_LE(double(n_auto), 1.06 * double(n_formula) + 5) << "chi=" << chi;
    auto o = options(chi, "pmm", 16);
    o.particle_grids = {"auto"};
    const auto r = vfe::stability_test(o).results.at(0);
    SCOPED_TRACE("chi=" + std::to_string(chi) + " n=" + std::to_string(r.grid_max));
    EXPECT_TRUE(r.stable) << "J = " << r.excess_jump << " > " << vfe::kDefaultJumpCriterion;
  }
}

// The default criterion is the direct method's jump at chi = 3: unstable below, stable at
// and above.
TEST(Stability, DirectIsUnstableBelowChi3) {
  for (double chi : {1.0, 2.0, 2.9, 2.99}) {
    const auto r = vfe::stability_test(options(chi, "direct", 16)).results.at(0);
    EXPECT_FALSE(r.stable) << "chi=" << chi;
    EXPECT_NEAR(r.max_jump, vfe::sub_element_jump(1, chi), 1e-9);
  }
  for (double chi : {3.0, 3.5}) {
    const auto r = vfe::stability_test(options(chi, "direct", 16)).results.at(0);
    EXPECT_TRUE(r.stable) << "chi=" << chi << " J=" << r.excess_jump;
  }
}

TEST(Stability, ExactHasNoExcessAndRunsAreDeterministic) {
  auto o = options(1.0, "exact", 4);
  EXPECT_NEAR(vfe::stability_test(o).results.at(0).excess_jump, 0.0, 1e-12);
  o = options(1.0, "pmm", 6);
  o.particle_grids = {"30", "auto"};
  o.threads = 1;
  const auto one = vfe::stability_test(o);
  o.threads = 2;
  const auto two = vfe::stability_test(o);
  ASSERT_EQ(one.results.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(one.results[i].excess_jump, two.results[i].excess_jump);
    EXPECT_EQ(one.results[i].worst_trajectory, two.results[i].worst_trajectory);
  }
  EXPECT_EQ(one.steps, 400);
}

TEST(Stability, FluxFormAndBadOptions) {
  auto o = options(2.0, "direct", 4);
  o.superficial_velocity = 0.1;
  o.fluid_dt = 1e-4;
  o.diameter = 1e-3;
  const auto rep = vfe::stability_test(o);
  EXPECT_NEAR(rep.flux_criterion, 0.1 * 1e-4 / 2e-3, 1e-15);
  const auto& r = rep.results.at(0);
  EXPECT_NEAR(r.psi_excess, r.excess_jump / rep.flux_criterion, 1e-12);
  EXPECT_FALSE(r.flux_stable);

  auto bad = options(1.0, "pmm", 2);
  bad.engine_options = "template=nonsense";
  try {
    vfe::stability_test(bad);
    FAIL() << "expected an error";
  } catch (const vfe::Error& e) {
    EXPECT_NE(std::string(e.what()).find("template"), std::string::npos) << e.what();
  }
  bad = options(-1.0, "pmm", 2);
  EXPECT_THROW(vfe::stability_test(bad), vfe::Error);
  bad = options(1.0, "pmm", 2);
  bad.fluid_dt = 1e-3;  // without a velocity
  EXPECT_THROW(vfe::stability_test(bad), vfe::Error);
}

TEST(Stability, ModelGivesOneSubElementAtLargeChiAndGrowsAsChiFalls) {
  for (const char* family : {"spherical", "fibonacci"}) {
    const auto m = vfe::fitted_jump_model(family);
    EXPECT_GT(m.a, 0);
    EXPECT_GT(m.b, 0);
    double last = 1e300;
    for (double chi : {0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 6.0}) {
      const double n = vfe::n_min_model(chi, m);
      EXPECT_LE(n, last);
      EXPECT_GE(n, 1.0);
      last = n;
    }
    // A stricter criterion needs more sub-elements.
    EXPECT_GT(vfe::n_min_model(1.0, m, vfe::kDefaultJumpCriterion / 2), vfe::n_min_model(1.0, m));
  }
  EXPECT_THROW(vfe::fitted_jump_model("voxel"), vfe::Error);
}

// A shaped particle: scaled to the volume-equivalent diameter, a random orientation per
// trajectory, measured against a fine pmm (exact takes spheres only).
TEST(Stability, ShapedParticleAgainstAFinePmm) {
  auto o = options(1.0, "pmm", 4);
  o.shape = "ellipsoid 1 0.6 0.4";
  o.reference_grid = 4000;
  o.particle_grids = {"auto", "125"};
  const auto rep = vfe::stability_test(o);
  ASSERT_EQ(rep.results.size(), 2u);
  const auto& fine = rep.results[0];
  const auto& coarse = rep.results[1];
  EXPECT_GT(fine.grid_max, coarse.grid_max);
  EXPECT_NEAR(static_cast<double>(coarse.grid_max), 125.0, 5.0);
  // The reference moves smoothly (its own sub-element jump pi/(6*4000) is ~1.3e-4), while
  // the whole particle's volume pi/6 would be a jump of 0.52.
  EXPECT_GT(fine.max_jump_exact, 0.0);
  EXPECT_LT(fine.max_jump_exact, 0.02);
  EXPECT_TRUE(fine.stable);
  EXPECT_GT(coarse.excess_jump, fine.excess_jump);
  // Deterministic.
  const auto again = vfe::stability_test(o);
  EXPECT_EQ(again.results[1].excess_jump, coarse.excess_jump);

  // direct moves the whole volume at once: a jump of about pi/6 per cell crossing.
  auto d = o;
  d.method = "direct";
  d.particle_grids.clear();
  const auto rd = vfe::stability_test(d);
  EXPECT_NEAR(rd.results[0].max_jump, std::numbers::pi / 6.0, 1e-9);
  EXPECT_FALSE(rd.results[0].stable);
}

TEST(Stability, ShapeErrorsAreNamed) {
  auto o = options(1.0, "pmm", 1);
  o.shape = "ellipsoid 1 0.6";
  try {
    (void)vfe::stability_test(o);
    FAIL() << "no error";
  } catch (const vfe::Error& e) {
    EXPECT_NE(std::string(e.what()).find("--shape"), std::string::npos) << e.what();
  }
  o.shape = "clump 10 0 0 1";  // the body lies 5 diameters from its origin
  o.reference_grid = 100;
  try {
    (void)vfe::stability_test(o);
    FAIL() << "no error";
  } catch (const vfe::Error& e) {
    EXPECT_NE(std::string(e.what()).find("reaches farther"), std::string::npos) << e.what();
  }
}

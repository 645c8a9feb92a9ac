// Stability stress test of docs/design.md section 8: single spheres (or shaped particles) moving in
// straight lines across cells in small steps; per step and cell the change of the void
// fraction of a method is compared with the exact one (shapes without an exact overlap,
// superquadrics and clumps: a fine pmm).
#pragma once

#include <vfe/vfe.h>

#include <cstdint>
#include <numbers>
#include <string>
#include <string_view>
#include <vector>

namespace vfe {

/// The default criterion of docs/design.md section 8: the direct method's jump at chi = 3.
inline constexpr double kDefaultJumpCriterion = std::numbers::pi / (6.0 * 27.0);

struct StabilityOptions {
  double chi = 1.0;               ///< cell size / particle diameter
  std::string method = "pmm";     ///< engine method (any the engine accepts)
  std::string engine_options;     ///< more engine options, e.g. "template=fibonacci orientation=none"
  /// Particle grids to test ("auto" or an integer); ignored (one run) for methods
  /// without a particle grid. Empty = {"auto"}.
  std::vector<std::string> particle_grids;
  double step = 1.0 / 200.0;      ///< step length as a fraction of the diameter
  double cells = 2.0;             ///< distance travelled, in cells
  int trajectories = 64;
  std::uint64_t seed = 1;         ///< trajectory i uses seed trajectory_seed(seed, i)
  double jump_criterion = kDefaultJumpCriterion;  ///< deps_crit for J
  /// Flux form (both > 0 to enable): psi = |deps| dx / (U_s dt_f), dx = chi * diameter.
  double superficial_velocity = 0;
  double fluid_dt = 0;
  double diameter = 1.0;          ///< particle diameter, in the length unit of U_s * dt_f
  int threads = 0;                ///< trajectories run in parallel; 0 = all cores
  /// A shaped particle instead of a sphere: an Engine::add_shape spec ("ellipsoid 1 0.6 0.4"),
  /// scaled so its volume-equivalent diameter is `diameter`, turned by a fixed random
  /// quaternion per trajectory (orientation=given). Its reference is exact for ellipsoids
  /// and triangle meshes, pmm with reference_grid sub-elements for superquadrics and
  /// clumps (which exact refuses). Empty = a sphere.
  std::string shape;
  std::int64_t reference_grid = 20000;  ///< particle_grid of the shapes' reference pmm
};

/// Result of one particle grid over all trajectories (maxima over trajectories, steps
/// and cells).
struct StabilityResult {
  std::string particle_grid;      ///< as requested ("auto", "40", or "-" without a grid)
  std::int64_t grid_min = 0;      ///< sub-elements per particle the engine used (min, max)
  std::int64_t grid_max = 0;
  double max_jump = 0;            ///< max |deps| of the method
  double max_jump_exact = 0;      ///< max |deps| of the reference (StabilityReport::reference) over the same steps
  double excess_jump = 0;         ///< J = max (|deps| - |deps_exact|)
  double mean_excess_jump = 0;    ///< mean over trajectories of each trajectory's J
  /// J in units of one sub-element's jump pi / (6 n chi^3) (n = grid_max); 0 without a grid.
  double excess_in_sub_elements = 0;
  int unstable_trajectories = 0;  ///< trajectories with J > jump_criterion
  bool stable = false;            ///< J <= jump_criterion on every trajectory
  /// Flux form (0 when not enabled): psi of the largest jump and of the excess jump J,
  /// and whether J's psi is <= 1 on every trajectory.
  double psi_max = 0;
  double psi_excess = 0;
  bool flux_stable = false;
  int worst_trajectory = -1;      ///< trajectory index where J is reached
};

struct StabilityReport {
  StabilityOptions options;       ///< as run (particle_grids filled in)
  std::int64_t steps = 0;         ///< steps per trajectory
  double flux_criterion = 0;      ///< U_s dt_f / dx: the deps the flux form allows (0 = off)
  std::string reference;          ///< the reference's options: "method=exact ..." or "method=pmm ... particle_grid=N"
  std::vector<StabilityResult> results;  ///< one per particle grid, in the given order
};

/// Seed of trajectory i (also its template orientation: the engine's option seed=).
VFE_API std::uint64_t trajectory_seed(std::uint64_t seed, int trajectory);

/// The reference's method options for these options: "method=exact" for spheres and the
/// shapes exact computes (ellipsoids, triangle meshes), "method=pmm particle_grid=N"
/// (N = reference_grid) for the others. Throws Error for a bad shape spec.
VFE_API std::string stability_reference(const StabilityOptions& options);

/// Runs the stress test. Deterministic for given options (any thread count). Throws
/// vfe::Error (invalid argument) for bad options, naming them.
VFE_API StabilityReport stability_test(const StabilityOptions& options);

/// The jump of one sub-element crossing a face: pi / (6 n chi^3).
inline double sub_element_jump(double n, double chi) {
  return std::numbers::pi / (6.0 * n * chi * chi * chi);
}

/// Jump model of docs/stability.md: in the stress test (step d/200) the excess jump of a
/// randomly rotated template of n sub-elements is J = pi / (6 n chi^3) * (b + a sqrt(n)).
struct JumpModel {
  double a = 0;  ///< growth with the crossings per step (scales as sqrt(step / d))
  double b = 0;  ///< crossings that coincide regardless of n
};

/// Fitted constants for a template family with orientation=random ("spherical" or
/// "fibonacci"); throws Error (invalid argument) for another name.
VFE_API JumpModel fitted_jump_model(std::string_view template_family);

/// Smallest n with J <= jump_criterion under the model (real-valued, >= 1):
/// n_min = ((C a + sqrt(C^2 a^2 + 4 C b chi^3)) / (2 chi^3))^2, C = pi / (6 jump_criterion).
VFE_API double n_min_model(double chi, const JumpModel& model, double jump_criterion = kDefaultJumpCriterion);

/// Flux form: the jump the host's flow allows, U_s dt_f / dx (psi = deps dx / (U_s dt_f) <= 1).
inline double flux_jump_criterion(double superficial_velocity, double fluid_dt, double cell_size) {
  return superficial_velocity * fluid_dt / cell_size;
}

/// particle_grid=auto: 5 * ceil(n_min_model(chi)) for the family's fitted model under the
/// given criterion (the engine then uses the nearest template size it can make).
VFE_API std::int64_t auto_particle_grid(double chi, std::string_view template_family,
                                double jump_criterion = kDefaultJumpCriterion);

}  // namespace vfe

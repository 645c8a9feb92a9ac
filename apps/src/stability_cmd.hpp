// `vfe stability`: the stability stress test of docs/design.md section 8 for any method, and the
// sweep over chi and particle grids that finds the empirical n_min(chi).
#pragma once

#include <vfe/stability.hpp>

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace spdlog {
class logger;
}

namespace vfe::apps {

struct StabilityCommand {
  std::vector<double> chi{1.0};
  std::vector<std::string> grids;         ///< particle grids; empty = auto (sweep: the ladder)
  std::string method = "pmm";
  std::vector<std::string> templates;     ///< template families; empty = the engine's default
  std::vector<std::string> orientations;  ///< orientations; empty = the engine's default
  std::string options;                    ///< more engine options
  double step = 1.0 / 200.0;              ///< fraction of the diameter
  int trajectories = 64;
  std::uint64_t seed = 1;
  double cells = 2.0;
  double jump_criterion = vfe::kDefaultJumpCriterion;
  double superficial_velocity = 0;        ///< U_s (flux form when > 0, with fluid_dt)
  double fluid_dt = 0;
  double diameter = 1.0;                  ///< particle diameter in the length unit of U_s * dt_f
  /// A shaped particle (Engine::add_shape spec) instead of a sphere, of volume-equivalent
  /// diameter `diameter`, turned by a fixed random quaternion per trajectory; empty = sphere.
  std::string shape;
  std::int64_t reference_grid = 20000;    ///< particle_grid of the shapes' reference pmm
  bool sweep = false;
  int threads = 0;
  std::filesystem::path output = "stability";
  std::shared_ptr<spdlog::logger> logger;  ///< progress; null = quiet
  std::ostream* table = nullptr;           ///< where the tables go; null = none
};

/// One tested (template, orientation, chi, particle grid).
struct StabilityRow {
  std::string template_family, orientation;
  double chi = 0;
  vfe::StabilityResult result;
};

/// n_min of one (template, orientation, chi) in a sweep.
struct NMinRow {
  std::string template_family, orientation;
  double chi = 0;
  std::int64_t n_min = -1;       ///< smallest tested n from which every larger tested n is stable; -1 = none
  double excess_at_n_min = 0;    ///< J there
  std::int64_t n_min_flux = -1;  ///< the same under the flux criterion (-1: none or not enabled)
  std::int64_t n_tested_max = 0; ///< largest n tested
};

struct StabilityOutcome {
  std::vector<StabilityRow> rows;
  std::vector<NMinRow> n_min;  ///< sweep only
  std::int64_t steps_per_trajectory_first = 0;
  double flux_criterion_first = 0;
  std::filesystem::path output;  ///< folder holding stability.csv/json (and n_min.csv)
};

/// The ladder of particle grids the sweep tries (requested sizes, ascending).
std::vector<std::string> default_sweep_grids();

/// Runs the test (or the sweep), writes stability.csv, stability.json (and n_min.csv),
/// prints the tables. Throws vfe::Error or std::runtime_error naming the problem.
StabilityOutcome run_stability(const StabilityCommand& command);

}  // namespace vfe::apps

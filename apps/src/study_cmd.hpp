// `vfe study`: run time against error of every method and setting of a scene at several
// cell sizes: the time per compute (median of repeats, methods timed in turn), the errors
// against the reference (docs/design.md section 8), the Pareto front per grid, and how a base family
// (pmm) compares with every other point at equal error and at equal cost.
#pragma once

#include "config.hpp"

#include <vfe/measures.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace spdlog {
class logger;
}

namespace vfe::apps {

struct StudyOptions {
  std::optional<std::filesystem::path> output;  ///< replaces the config's output folder
  std::optional<int> threads;                   ///< replaces the config's threads
  std::optional<int> repeats;                   ///< replaces the config's repeats
  std::optional<std::vector<double>> chi;       ///< replaces the config's chi list
  std::string base = "pmm";                     ///< the family compared with every other point
  /// Only these families (method labels) of the config; empty = every one. An unknown
  /// label is a ConfigError.
  std::vector<std::string> families;
  std::shared_ptr<spdlog::logger> logger;       ///< progress; null = a quiet app logger
  std::ostream* table = nullptr;                ///< where the tables go; null = none
};

/// One point of the study: a method family at one setting on one grid.
struct StudyPoint {
  std::string mesh;
  std::string mesh_type = "cartesian";  ///< "cartesian", "rectilinear" or "polymesh"
  std::string family;   ///< the method entry's label (a line in the plot)
  std::string method;   ///< engine method
  std::string setting;  ///< the setting's option string ("" for a method without settings)
  std::string options;  ///< the engine's full option string
  bool is_reference = false;
  double chi = 0;        ///< cell size / mean particle diameter
  /// Cube root of the cell volume; on rectilinear grids and polyMeshes the mean over the
  /// cells of the cube root of each cell's volume.
  double cell_size = 0;
  std::array<std::int64_t, 3> grid{0, 0, 0};  ///< cells per axis; {0, 0, 0} on a polyMesh
  std::int64_t cells = 0;
  std::int64_t particles = 0;
  int threads = 0;
  int repeats = 0;
  double time_median_ms = 0;
  double time_min_ms = 0;
  vfe::AccuracyMeasures accuracy;
  std::int64_t fast_path_particles = 0;
  std::int64_t sub_elements = 0;
  std::int64_t particle_grid_min = 0;
  std::int64_t particle_grid_max = 0;
  bool pareto = false;  ///< no point of the same grid is both faster and more accurate (L1)
  /// The mesh kind does not offer the method (VFE_ERROR_UNSUPPORTED at configure, e.g.
  /// trilinear on a polyMesh): no times or errors (NaN), note says why; never on the front.
  bool skipped = false;
  std::string note;
};

/// The base family against one point of another family on the same grid, by L1 (errors
/// below 1e-12 count as 0). Interpolation is log-log along the base family's own front;
/// NaN where the base family's settings do not reach.
struct StudyComparison {
  std::string mesh;
  double chi = 0;
  std::string family, setting;
  double time_ms = 0, l1 = 0;
  double base_time_at_error = 0;  ///< base family's time at this point's L1
  double speedup = 0;             ///< time_ms / base_time_at_error
  std::string speedup_note;       ///< "" exact; ">=" the base's cheapest point is already more accurate; "n/a"
  double base_error_at_time = 0;  ///< base family's L1 at this point's time
  double accuracy_gain = 0;       ///< l1 / base_error_at_time
  std::string gain_note;          ///< "" exact; ">=" at least (beyond the base's costliest point); "n/a"
};

struct StudyResult {
  std::vector<StudyPoint> points;
  std::vector<StudyComparison> comparisons;
  std::filesystem::path output;  ///< folder holding study.csv, study.json, comparisons.csv
};

/// Runs the study of a scene config (its meshes: Cartesian, rectilinear or OpenFOAM polyMesh,
/// and its chi grids; every method at every setting). A method the mesh kind refuses with
/// VFE_ERROR_UNSUPPORTED is a skipped point. Throws ConfigError, DumpError, vfe::Error or std::runtime_error naming the problem.
StudyResult run_study(const SceneConfig& config, const StudyOptions& options);

/// Marks the Pareto-optimal points of each mesh (time against L1); skipped points are neither
/// on the front nor dominate.
void mark_pareto(std::vector<StudyPoint>& points);

/// A family's front: (time, error) pairs sorted by time, errors strictly decreasing.
struct Front {
  std::vector<double> time, error;
};
/// The front of the given points (time, error); dominated points are left out.
Front make_front(std::vector<std::pair<double, double>> points);
/// Time the front needs for error e: log-log interpolation; the cheapest time when it
/// already reaches e (note ">="); NaN when it never does (note "n/a").
double front_time_at_error(const Front& f, double e, std::string* note);
/// Error the front reaches in time t: log-log interpolation; the last error when t is
/// beyond its costliest point (note ">="); NaN when t is below its cheapest (note "n/a").
double front_error_at_time(const Front& f, double t, std::string* note);

}  // namespace vfe::apps

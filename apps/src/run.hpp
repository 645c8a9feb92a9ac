// The run driver of `vfe run`: reads the scene, computes every method on every mesh,
// times it, measures it against the reference and writes the reports.
#pragma once

#include "cli_command.hpp"

#include "config.hpp"
#include "report.hpp"

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <optional>
#include <vector>

namespace spdlog {
class logger;
}

namespace vfe::apps {

/// The app's own logger ("vfe-app", coloured on stderr), not registered with spdlog, so a
/// host's or the engine's logging is left alone. quiet keeps only warnings and errors.
std::shared_ptr<spdlog::logger> make_app_logger(bool quiet);

struct RunOptions {
  std::optional<std::filesystem::path> output;  ///< replaces the config's output folder
  std::optional<int> threads;                   ///< replaces the config's threads
  std::optional<int> repeats;                   ///< replaces the config's repeats
  bool vtk = false;   ///< also write <mesh>.vti / <mesh>.vtu (or vtk: true in the config)
  /// also write OpenFOAM fields <mesh>/0/voidfraction_<label> and <mesh>/0/voidfraction
  /// (the method with the engine's default options, else the first) on polymesh meshes
  /// (or foam: true in the config)
  bool foam = false;
  std::shared_ptr<spdlog::logger> logger;       ///< progress; null = a quiet app logger
  std::ostream* table = nullptr;                ///< where the tables go; null = none
};

/// One method's compute of one frame of a series on one mesh, and the jump of its void
/// fraction from the previous frame against the reference's (NaN on the first frame, or
/// without a reference on the mesh).
struct FrameRow {
  std::string mesh;
  std::string label;
  std::string method;
  double chi = 0;
  std::int64_t frame = 0;  ///< 0-based index in the series
  std::int64_t timestep = 0;
  double time = 0;  ///< timestep * dem_dt, or the timestep without dem_dt
  double ms = 0;    ///< the compute's wall time (the first frame's includes building templates)
  double max_excess = 0, mean_excess = 0, max_exact_jump = 0;
  std::int64_t changed_cells = 0;  ///< cells where either field changed (the mean's count)
};

/// One method over a whole series on one mesh: the jumps of every pair of consecutive frames
/// together (max over cells and pairs, mean over every changed cell of every pair).
struct SeriesRow {
  std::string mesh;
  std::string label;
  std::string method;
  double chi = 0;
  std::int64_t frames = 0;
  double ms_median = 0;  ///< median compute time over the frames
  double max_excess = 0, mean_excess = 0, max_exact_jump = 0;  ///< NaN with fewer than 2 frames or no reference
  bool skipped = false;  ///< not supported on this mesh; note says why
  std::string note;
};

struct RunResult {
  std::vector<ResultRow> rows;   ///< one frame: a row per mesh and method
  std::vector<FrameRow> frames;  ///< a series: a row per mesh, method and frame
  std::vector<SeriesRow> series; ///< a series: a row per mesh and method
  std::filesystem::path output;  ///< folder holding results.json, results.csv (and field files)
};

/// Runs the scene: every method on every mesh, timed and measured against the reference.
/// A method (or reference) the engine does not support on a mesh (VFE_ERROR_UNSUPPORTED,
/// e.g. exact on a polyMesh) gives a skipped row with the reason and a warning; without a
/// reference on a mesh, the error measures there are NaN. Throws DumpError, ConfigError, vfe::Error or std::runtime_error with a
/// message that names the problem.
RunResult run_scene(const SceneConfig& config, const RunOptions& options);

/// Runs a scene whose particles are a series of frames (config.series): per mesh and method
/// every frame in timestep order on one engine (so incremental=1 in the options carries
/// over), timed, with the jump between consecutive frames against the reference. Writes
/// frames.csv and frame_jumps.csv, with vtk a .pvd per mesh of per-frame .vti/.vtu files
/// and particles.pvd of per-frame .vtp files, with foam an OpenFOAM time folder per frame on
/// polymesh meshes. Throws as run_scene.
RunResult run_series(const SceneConfig& config, const RunOptions& options);

/// Replaces a series' timesteps range by "FROM:TO" (either may be empty: no bound), as
/// `vfe run --timesteps` does. Throws ConfigError for bad text or a scene of one frame.
void set_timesteps(SceneConfig& config, const std::string& range);

/// Adds `vfe run` and its options to the tool (help text and checks included).
CliCommand register_run(CLI::App& app);

}  // namespace vfe::apps

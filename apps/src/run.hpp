// The run driver of `vfe run`: reads the scene, computes every method on every mesh,
// times it, measures it against the reference and writes the reports.
#pragma once

#include "cli_command.hpp"

#include "config.hpp"
#include "report.hpp"

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

struct RunResult {
  std::vector<ResultRow> rows;
  std::filesystem::path output;  ///< folder holding results.json, results.csv (and field files)
};

/// Runs the scene: every method on every mesh, timed and measured against the reference.
/// A method (or reference) the engine does not support on a mesh (VFE_ERROR_UNSUPPORTED,
/// e.g. exact on a polyMesh) gives a skipped row with the reason and a warning; without a
/// reference on a mesh, the error measures there are NaN. Throws DumpError, ConfigError, vfe::Error or std::runtime_error with a
/// message that names the problem.
RunResult run_scene(const SceneConfig& config, const RunOptions& options);

/// Adds `vfe run` and its options to the tool (help text and checks included).
CliCommand register_run(CLI::App& app);

}  // namespace vfe::apps

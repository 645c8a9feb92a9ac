// Reports of `vfe run`: a text table per mesh, results.json and results.csv.
#pragma once

#include "text_format.hpp"

#include <vfe/engine.hpp>
#include <vfe/measures.hpp>

#include <spdlog/logger.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

namespace vfe::apps {

/// One mesh x method result.
struct ResultRow {
  std::string mesh;
  std::string mesh_type = "cartesian";  ///< "cartesian" or "polymesh"
  std::string label;
  std::string method;
  std::string options;  ///< the engine's full option string for this run
  bool is_reference = false;
  /// Not run on this mesh (the method is not supported there); note says why, and the
  /// measures are NaN.
  bool skipped = false;
  std::string note;
  std::array<std::int64_t, 3> grid{0, 0, 0};  ///< Cartesian cells per direction (0 on a polyMesh)
  std::int64_t cells = 0;
  double cell_size = 0;  ///< cube root of the (mean) cell volume
  double chi = 0;        ///< cell_size / mean particle diameter
  std::int64_t particles = 0;
  int threads = 0;  ///< threads used (0 in the config = all, resolved to the count)
  int repeats = 0;
  double time_median_ms = 0;
  double time_min_ms = 0;
  double particles_per_s = 0;
  double sub_elements_per_s = 0;
  std::int64_t sub_elements = 0;
  std::int64_t fast_path_particles = 0;
  std::int64_t particle_grid_min = 0;
  std::int64_t particle_grid_max = 0;
  vfe::AccuracyMeasures accuracy;
  double particle_volume = 0;
  double deposited_volume = 0;
  double dropped_volume = 0;
  double clipped_volume = 0;
  std::int64_t outside_particles = 0;
  std::int64_t overfull_cells = 0;  ///< cells holding more solid than their volume (eps < 0)
  double overfull_volume = 0;       ///< their solid volume beyond the cell volume, summed
};

/// Facts of the whole run, written at the top of results.json.
struct RunInfo {
  std::string scene;
  std::string particles_file;  ///< file name of the dump
  std::int64_t timestep = 0;
  std::int64_t particles = 0;
  double particle_volume = 0;
  double mean_diameter = 0;
  std::string reference;
  int threads = 0;
  int repeats = 0;
  std::string options;
  std::string version;
};

/// Cells of the last compute that hold more solid than their volume, and the excess.
struct OverfullFacts {
  std::int64_t cells = 0;
  double volume = 0;
};
OverfullFacts overfull_facts(const vfe::Engine& engine);

/// A warning line when some cells are overfull: mesh, method, the count, the excess as a
/// fraction of the particle volume, and how to avoid it. Nothing when none are.
void warn_overfull(spdlog::logger& log, const std::string& mesh, const std::string& method, const OverfullFacts& facts,
                   double particle_volume);

/// "a-b", or "a" when a == b.
std::string grid_range(std::int64_t lo, std::int64_t hi);

/// Prints the table of one mesh's rows (a title line, a header, one line per row, then the
/// reasons of skipped rows). Measures that are NaN (no reference) print as "-".
void print_table(std::ostream& out, const std::string& title, const std::vector<ResultRow>& rows);

void write_json(const std::filesystem::path& file, const RunInfo& info, const std::vector<ResultRow>& rows);
void write_csv(const std::filesystem::path& file, const RunInfo& info, const std::vector<ResultRow>& rows);

}  // namespace vfe::apps

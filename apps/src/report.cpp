#include "report.hpp"

#include "text_format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace vfe::apps {

namespace {

struct Column {
  std::string head;
  bool left = false;  ///< only the first column (the method) is
};

}  // namespace

OverfullFacts overfull_facts(const vfe::Engine& engine) {
  return {static_cast<std::int64_t>(engine.last_report_value("overfull_cells")),
          engine.last_report_value("overfull_volume")};
}

void warn_overfull(spdlog::logger& log, const std::string& mesh, const std::string& method, const OverfullFacts& facts,
                   double particle_volume) {
  if (facts.cells <= 0) return;
  log.warn("mesh '{}', method '{}': {} cell(s) hold more solid than their volume (excess {:.3e} of the particle "
           "volume, void fraction below 0 there); to avoid it use a bed that lies inside the mesh, outside=drop, "
           "method exact or a finer pmm, or set alpha_min",
           mesh, method, facts.cells, particle_volume > 0 ? facts.volume / particle_volume : 0.0);
}

std::string grid_range(std::int64_t lo, std::int64_t hi) {
  return lo == hi ? std::to_string(lo) : std::to_string(lo) + "-" + std::to_string(hi);
}

void print_table(std::ostream& out, const std::string& title, const std::vector<ResultRow>& rows) {
  const std::vector<Column> cols = {{"method", true}, {"ms/compute"}, {"particles/s"}, {"sub-el/s"},
                                    {"grid"},         {"theta"},      {"max|err|"},    {"L1"},
                                    {"vol err"},      {"outside"},    {"dropped"}};
  std::vector<std::vector<std::string>> cells;
  std::vector<std::string> notes;
  for (const auto& r : rows) {
    const std::string label = r.label + (r.is_reference ? " *" : "");
    if (r.skipped) {
      std::vector<std::string> row(cols.size(), "-");
      row[0] = label;
      row[1] = "skipped";
      cells.push_back(row);
      notes.push_back(r.label + " skipped: " + r.note);
      continue;
    }
    const double dropped_rel = r.particle_volume > 0 ? r.dropped_volume / r.particle_volume : 0.0;
    cells.push_back({label, printf_number("%.3f", r.time_median_ms), printf_number("%.3g", r.particles_per_s),
                     printf_number("%.3g", r.sub_elements_per_s), grid_range(r.particle_grid_min, r.particle_grid_max),
                     table_number("%.3e", r.accuracy.theta), table_number("%.3e", r.accuracy.max_error),
                     table_number("%.3e", r.accuracy.l1), table_number("%.1e", r.accuracy.volume_error),
                     std::to_string(r.outside_particles), printf_number("%.1e", dropped_rel)});
    if (!r.note.empty()) notes.push_back(r.label + ": " + r.note);
  }
  out << title << '\n';
  std::vector<std::string> head;
  for (const auto& c : cols) head.push_back(c.head);
  cells.insert(cells.begin(), head);
  print_columns(out, cells, 1);
  out << "(* reference; errors against it; outside = particles partly outside the mesh; dropped = dropped "
         "volume / particle volume)\n";
  for (const auto& n : notes) out << "  " << n << '\n';
  out.flush();
}

void write_json(const std::filesystem::path& file, const RunInfo& info, const std::vector<ResultRow>& rows) {
  std::ostringstream o;
  o << "{\n";
  o << "  \"scene\": " << json_string(info.scene) << ",\n";
  o << "  \"vfe_version\": " << json_string(info.version) << ",\n";
  o << "  \"particles_file\": " << json_string(info.particles_file) << ",\n";
  o << "  \"timestep\": " << info.timestep << ",\n";
  o << "  \"particles\": " << info.particles << ",\n";
  o << "  \"particle_volume\": " << json_number(info.particle_volume) << ",\n";
  o << "  \"mean_diameter\": " << json_number(info.mean_diameter) << ",\n";
  o << "  \"reference\": " << json_string(info.reference) << ",\n";
  o << "  \"threads\": " << info.threads << ",\n";
  o << "  \"repeats\": " << info.repeats << ",\n";
  o << "  \"options\": " << json_string(info.options) << ",\n";
  o << "  \"rows\": [";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    o << (i ? ",\n" : "\n") << "    {";
    o << "\"mesh\": " << json_string(r.mesh) << ", \"mesh_type\": " << json_string(r.mesh_type)
      << ", \"method\": " << json_string(r.label)
      << ", \"engine_method\": " << json_string(r.method) << ", \"options\": " << json_string(r.options)
      << ", \"reference\": " << (r.is_reference ? "true" : "false")
      << ", \"status\": " << json_string(r.skipped ? "skipped" : "ok") << ", \"note\": " << json_string(r.note);
    if (r.mesh_type == "polymesh")
      o << ", \"grid\": null";
    else
      o << ", \"grid\": [" << r.grid[0] << ", " << r.grid[1] << ", " << r.grid[2] << "]";
    o << ", \"cells\": " << r.cells << ", \"cell_size\": " << json_number(r.cell_size)
      << ", \"chi\": " << json_number(r.chi) << ", \"particles\": " << r.particles << ", \"threads\": " << r.threads
      << ", \"repeats\": " << r.repeats << ", \"time_median_ms\": " << json_number(r.time_median_ms)
      << ", \"time_min_ms\": " << json_number(r.time_min_ms) << ", \"particles_per_s\": " << json_number(r.particles_per_s)
      << ", \"sub_elements_per_s\": " << json_number(r.sub_elements_per_s) << ", \"sub_elements\": " << r.sub_elements
      << ", \"fast_path_particles\": " << r.fast_path_particles
      << ", \"particle_grid_min\": " << r.particle_grid_min << ", \"particle_grid_max\": " << r.particle_grid_max
      << ", \"theta\": " << json_number(r.accuracy.theta) << ", \"max_error\": " << json_number(r.accuracy.max_error)
      << ", \"l1\": " << json_number(r.accuracy.l1) << ", \"volume_error\": " << json_number(r.accuracy.volume_error)
      << ", \"cells_compared\": " << r.accuracy.cells_compared
      << ", \"particle_volume\": " << json_number(r.particle_volume) << ", \"deposited_volume\": " << json_number(r.deposited_volume)
      << ", \"dropped_volume\": " << json_number(r.dropped_volume) << ", \"clipped_volume\": " << json_number(r.clipped_volume)
      << ", \"outside_particles\": " << r.outside_particles << ", \"overfull_cells\": " << r.overfull_cells
      << ", \"overfull_volume\": " << json_number(r.overfull_volume) << "}";
  }
  o << "\n  ]\n}\n";
  std::ofstream out(file);
  check_written(out, file);
  out << o.str();
  out.flush();
  check_written(out, file);
}

void write_csv(const std::filesystem::path& file, const RunInfo& info, const std::vector<ResultRow>& rows) {
  std::ostringstream o;
  o << "scene,mesh,method,engine_method,options,reference,nx,ny,nz,cells,cell_size,chi,particles,threads,"
       "repeats,time_median_ms,time_min_ms,particles_per_s,sub_elements_per_s,sub_elements,"
       "fast_path_particles,particle_grid_min,particle_grid_max,theta,max_error,l1,volume_error,"
       "cells_compared,particle_volume,deposited_volume,dropped_volume,clipped_volume,outside_particles,"
       "mesh_type,status,note,overfull_cells,overfull_volume\n";
  for (const auto& r : rows) {
    const bool poly = r.mesh_type == "polymesh";  // no nx, ny, nz
    o << csv_field(info.scene) << ',' << csv_field(r.mesh) << ',' << csv_field(r.label) << ','
      << csv_field(r.method) << ',' << csv_field(r.options) << ',' << (r.is_reference ? 1 : 0) << ','
      << (poly ? "" : std::to_string(r.grid[0])) << ',' << (poly ? "" : std::to_string(r.grid[1])) << ','
      << (poly ? "" : std::to_string(r.grid[2])) << ',' << r.cells << ',' << csv_number(r.cell_size) << ','
      << csv_number(r.chi) << ',' << r.particles << ',' << r.threads << ',' << r.repeats << ','
      << csv_number(r.time_median_ms) << ',' << csv_number(r.time_min_ms) << ',' << csv_number(r.particles_per_s) << ','
      << csv_number(r.sub_elements_per_s) << ',' << r.sub_elements << ',' << r.fast_path_particles << ','
      << r.particle_grid_min << ',' << r.particle_grid_max << ',' << csv_number(r.accuracy.theta) << ','
      << csv_number(r.accuracy.max_error) << ',' << csv_number(r.accuracy.l1) << ',' << csv_number(r.accuracy.volume_error) << ','
      << r.accuracy.cells_compared << ',' << csv_number(r.particle_volume) << ',' << csv_number(r.deposited_volume) << ','
      << csv_number(r.dropped_volume) << ',' << csv_number(r.clipped_volume) << ',' << r.outside_particles << ','
      << csv_field(r.mesh_type) << ',' << (r.skipped ? "skipped" : "ok") << ',' << csv_field(r.note) << ','
      << r.overfull_cells << ',' << csv_number(r.overfull_volume) << '\n';
  }
  std::ofstream out(file);
  check_written(out, file);
  out << o.str();
  out.flush();
  check_written(out, file);
}

}  // namespace vfe::apps

#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace vfe::apps {

namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

/// Shortest text that reads back to the same double; JSON has no NaN/Inf: null.
std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  for (int p = 6; p <= 17; ++p) {
    std::snprintf(buf, sizeof buf, "%.*g", p, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

/// CSV has no null: non-finite values are written as nan/inf.
std::string cnum(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return num(v);
}

std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    switch (c) {
      case '"': o += "\\\""; break;
      case '\\': o += "\\\\"; break;
      case '\n': o += "\\n"; break;
      case '\t': o += "\\t"; break;
      case '\r': o += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          o += buf;
        } else {
          o += c;
        }
    }
  }
  return o + "\"";
}

void check_stream(const std::ofstream& out, const std::filesystem::path& file) {
  if (!out)
    throw std::runtime_error(file.string() + ": cannot write the file; check that the output folder "
                                             "is writable and the disk is not full");
}

struct Column {
  std::string head;
  bool left = false;
};

}  // namespace

std::string grid_range(std::int64_t lo, std::int64_t hi) {
  return lo == hi ? std::to_string(lo) : std::to_string(lo) + "-" + std::to_string(hi);
}

void print_table(std::ostream& out, const std::string& title, const std::vector<ResultRow>& rows) {
  const std::vector<Column> cols = {{"method", true}, {"ms/compute"}, {"particles/s"}, {"sub-el/s"},
                                    {"grid"},         {"theta"},      {"max|err|"},    {"L1"},
                                    {"vol err"},      {"outside"},    {"dropped"}};
  // NaN (no reference on this mesh) as "-".
  auto f = [](const char* format, double v) { return std::isnan(v) ? std::string("-") : fmt(format, v); };
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
    cells.push_back({label, fmt("%.3f", r.time_median_ms), fmt("%.3g", r.particles_per_s),
                     fmt("%.3g", r.sub_elements_per_s), grid_range(r.particle_grid_min, r.particle_grid_max),
                     f("%.3e", r.accuracy.theta), f("%.3e", r.accuracy.max_error), f("%.3e", r.accuracy.l1),
                     f("%.1e", r.accuracy.volume_error), std::to_string(r.outside_particles),
                     fmt("%.1e", dropped_rel)});
    if (!r.note.empty()) notes.push_back(r.label + ": " + r.note);
  }
  std::vector<std::size_t> width(cols.size());
  for (std::size_t c = 0; c < cols.size(); ++c) {
    width[c] = cols[c].head.size();
    for (const auto& row : cells) width[c] = std::max(width[c], row[c].size());
  }
  auto line = [&](const std::vector<std::string>& v) {
    std::string s;
    for (std::size_t c = 0; c < cols.size(); ++c) {
      const std::string pad(width[c] - v[c].size(), ' ');
      if (c) s += "  ";
      s += cols[c].left ? v[c] + pad : pad + v[c];
    }
    while (!s.empty() && s.back() == ' ') s.pop_back();
    out << s << '\n';
  };
  out << title << '\n';
  std::vector<std::string> head;
  for (const auto& c : cols) head.push_back(c.head);
  line(head);
  std::size_t total = 2 * (cols.size() - 1);
  for (auto w : width) total += w;
  out << std::string(total, '-') << '\n';
  for (const auto& row : cells) line(row);
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
  o << "  \"particle_volume\": " << num(info.particle_volume) << ",\n";
  o << "  \"mean_diameter\": " << num(info.mean_diameter) << ",\n";
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
    o << ", \"cells\": " << r.cells << ", \"cell_size\": " << num(r.cell_size)
      << ", \"chi\": " << num(r.chi) << ", \"particles\": " << r.particles << ", \"threads\": " << r.threads
      << ", \"repeats\": " << r.repeats << ", \"time_median_ms\": " << num(r.time_median_ms)
      << ", \"time_min_ms\": " << num(r.time_min_ms) << ", \"particles_per_s\": " << num(r.particles_per_s)
      << ", \"sub_elements_per_s\": " << num(r.sub_elements_per_s) << ", \"sub_elements\": " << r.sub_elements
      << ", \"fast_path_particles\": " << r.fast_path_particles
      << ", \"particle_grid_min\": " << r.particle_grid_min << ", \"particle_grid_max\": " << r.particle_grid_max
      << ", \"theta\": " << num(r.accuracy.theta) << ", \"max_error\": " << num(r.accuracy.max_error)
      << ", \"l1\": " << num(r.accuracy.l1) << ", \"volume_error\": " << num(r.accuracy.volume_error)
      << ", \"cells_compared\": " << r.accuracy.cells_compared
      << ", \"particle_volume\": " << num(r.particle_volume) << ", \"deposited_volume\": " << num(r.deposited_volume)
      << ", \"dropped_volume\": " << num(r.dropped_volume) << ", \"clipped_volume\": " << num(r.clipped_volume)
      << ", \"outside_particles\": " << r.outside_particles << "}";
  }
  o << "\n  ]\n}\n";
  std::ofstream out(file);
  check_stream(out, file);
  out << o.str();
  out.flush();
  check_stream(out, file);
}

void write_csv(const std::filesystem::path& file, const RunInfo& info, const std::vector<ResultRow>& rows) {
  std::ostringstream o;
  o << "scene,mesh,method,engine_method,options,reference,nx,ny,nz,cells,cell_size,chi,particles,threads,"
       "repeats,time_median_ms,time_min_ms,particles_per_s,sub_elements_per_s,sub_elements,"
       "fast_path_particles,particle_grid_min,particle_grid_max,theta,max_error,l1,volume_error,"
       "cells_compared,particle_volume,deposited_volume,dropped_volume,clipped_volume,outside_particles,"
       "mesh_type,status,note\n";
  for (const auto& r : rows) {
    const bool poly = r.mesh_type == "polymesh";  // no nx, ny, nz
    o << csv_field(info.scene) << ',' << csv_field(r.mesh) << ',' << csv_field(r.label) << ','
      << csv_field(r.method) << ',' << csv_field(r.options) << ',' << (r.is_reference ? 1 : 0) << ','
      << (poly ? "" : std::to_string(r.grid[0])) << ',' << (poly ? "" : std::to_string(r.grid[1])) << ','
      << (poly ? "" : std::to_string(r.grid[2])) << ',' << r.cells << ',' << cnum(r.cell_size) << ','
      << cnum(r.chi) << ',' << r.particles << ',' << r.threads << ',' << r.repeats << ','
      << cnum(r.time_median_ms) << ',' << cnum(r.time_min_ms) << ',' << cnum(r.particles_per_s) << ','
      << cnum(r.sub_elements_per_s) << ',' << r.sub_elements << ',' << r.fast_path_particles << ','
      << r.particle_grid_min << ',' << r.particle_grid_max << ',' << cnum(r.accuracy.theta) << ','
      << cnum(r.accuracy.max_error) << ',' << cnum(r.accuracy.l1) << ',' << cnum(r.accuracy.volume_error) << ','
      << r.accuracy.cells_compared << ',' << cnum(r.particle_volume) << ',' << cnum(r.deposited_volume) << ','
      << cnum(r.dropped_volume) << ',' << cnum(r.clipped_volume) << ',' << r.outside_particles << ','
      << csv_field(r.mesh_type) << ',' << (r.skipped ? "skipped" : "ok") << ',' << csv_field(r.note) << '\n';
  }
  std::ofstream out(file);
  check_stream(out, file);
  out << o.str();
  out.flush();
  check_stream(out, file);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

void write_text_file(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  out.flush();
  check_stream(out, file);
}

}  // namespace vfe::apps

#include "frame_series.hpp"

#include "dump_reader.hpp"

#include <glob.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace vfe::apps {

namespace fs = std::filesystem;

namespace {

std::string where(const SceneConfig& c) {
  const int line = c.series ? c.series->line : 0;
  return c.source.string() + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": particles";
}

/// Reorders every per-particle array of p by the permutation order (new i = old order[i]).
void permute(SceneParticles& p, const std::vector<std::size_t>& order) {
  auto apply = [&](auto& v, std::size_t per) {
    if (v.empty()) return;
    auto out = v;
    for (std::size_t i = 0; i < order.size(); ++i)
      for (std::size_t k = 0; k < per; ++k) out[per * i + k] = v[per * order[i] + k];
    v.swap(out);
  };
  apply(p.centres, 3);
  apply(p.radii, 1);
  apply(p.orientations, 4);
  apply(p.velocities, 3);
  apply(p.shape_ids, 1);
  apply(p.ids, 1);
}

/// Orders the particles by id; a repeated id is an error naming the file and timestep.
void order_by_id(SceneParticles& p) {
  std::vector<std::size_t> order(p.ids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return p.ids[a] < p.ids[b]; });
  for (std::size_t i = 1; i < order.size(); ++i)
    if (p.ids[order[i]] == p.ids[order[i - 1]])
      throw DumpError(p.source_name + ": timestep " + std::to_string(p.timestep) + ": particle id " +
                      std::to_string(p.ids[order[i]]) + " appears twice; each particle needs its own id");
  if (!std::is_sorted(order.begin(), order.end())) permute(p, order);
}

}  // namespace

std::vector<fs::path> series_files(const FrameSeriesSpec& s, const std::string& source) {
  std::vector<fs::path> files;
  for (const std::string& pattern : s.files) {
    if (pattern.find_first_of("*?[") == std::string::npos) {
      std::error_code ec;
      if (!fs::exists(pattern, ec))
        throw ConfigError(source + ": particles: " + pattern +
                          ": no such file; check the path (relative to the config's folder)");
      files.emplace_back(pattern);
      continue;
    }
    glob_t g{};
    const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
    std::vector<fs::path> matches;
    for (std::size_t i = 0; rc == 0 && i < g.gl_pathc; ++i) matches.emplace_back(g.gl_pathv[i]);
    ::globfree(&g);
    if (matches.empty())
      throw ConfigError(source + ": particles: no file matches '" + pattern +
                        "'; check the pattern (relative to the config's folder)");
    files.insert(files.end(), matches.begin(), matches.end());
  }
  return files;
}

std::vector<SceneParticles> load_frame_series(const SceneConfig& c) {
  if (!c.series) throw ConfigError(c.source.string() + ": the particles are not a series of frames");
  const FrameSeriesSpec& s = *c.series;
  const std::vector<double> shape_volumes = config_shape_volumes(c);
  std::vector<SceneParticles> frames;
  std::vector<fs::path> frame_file;  // the file of each frame, for messages
  for (const fs::path& file : series_files(s, c.source.string())) {
    DumpReader reader(file.string());
    DumpFrame f;
    bool any = false;
    while (reader.next(f)) {
      any = true;
      if ((s.from_timestep && f.timestep < *s.from_timestep) || (s.to_timestep && f.timestep > *s.to_timestep))
        continue;
      frames.push_back(particles_from_dump(c, std::move(f), file, shape_volumes));
      frame_file.push_back(file);
      f = DumpFrame{};
    }
    if (!any)
      throw DumpError(file.string() + ": contains no frame (empty file); expected a LIGGGHTS/LAMMPS text dump");
  }
  std::vector<std::size_t> order(frames.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return frames[a].timestep < frames[b].timestep; });
  for (std::size_t i = 1; i < order.size(); ++i)
    if (frames[order[i]].timestep == frames[order[i - 1]].timestep)
      throw DumpError(frame_file[order[i]].string() + ": timestep " + std::to_string(frames[order[i]].timestep) +
                      " is also in " + frame_file[order[i - 1]].string() +
                      "; a series needs one frame per timestep (remove the overlapping dump)");

  const auto count = static_cast<std::int64_t>(order.size());
  const std::int64_t first = s.first_frame < 0 ? count + s.first_frame : s.first_frame;
  const std::int64_t last = s.last_frame < 0 ? count + s.last_frame : s.last_frame;
  std::string range;
  if (s.from_timestep || s.to_timestep)
    range = " with timesteps in [" + (s.from_timestep ? std::to_string(*s.from_timestep) : std::string("-")) + ", " +
            (s.to_timestep ? std::to_string(*s.to_timestep) : std::string("-")) + "]";
  if (count == 0)
    throw ConfigError(where(c) + ": no frame" + range + " in " + std::to_string(s.files.size()) +
                      " file pattern(s); widen timesteps: [from, to]");
  if (first < 0 || last >= count || first > last)
    throw ConfigError(where(c) + ": frames [" + std::to_string(s.first_frame) + ", " + std::to_string(s.last_frame) +
                      "] is outside the " + std::to_string(count) + " frame(s)" + range +
                      " (0-based, negative from the end)");

  std::vector<SceneParticles> series;
  for (std::int64_t k = first; k <= last; ++k) series.push_back(std::move(frames[order[static_cast<std::size_t>(k)]]));
  for (SceneParticles& p : series) {
    if (p.ids.empty() != series.front().ids.empty())
      throw DumpError(p.source_name + ": timestep " + std::to_string(p.timestep) + (p.ids.empty() ? " has no" : " has an") +
                      " id column and the series' first frame (" + series.front().source_name +
                      ") does not; dump every frame with the same columns");
    if (!p.ids.empty()) {
      order_by_id(p);
    } else if (p.n != series.front().n) {
      throw DumpError(p.source_name + ": timestep " + std::to_string(p.timestep) + " has " + std::to_string(p.n) +
                      " particles, the series' first frame (" + series.front().source_name + ", timestep " +
                      std::to_string(series.front().timestep) + ") has " + std::to_string(series.front().n) +
                      "; without an id column particles cannot be matched between frames: dump the ids too");
    }
  }
  return series;
}

double frame_time(std::int64_t timestep, double dem_dt) {
  return dem_dt > 0 ? static_cast<double>(timestep) * dem_dt : static_cast<double>(timestep);
}

double FrameJump::mean_excess() const {
  return changed_cells > 0 ? excess_sum / static_cast<double>(changed_cells) : 0.0;
}

void FrameJump::add(const FrameJump& o) {
  max_excess = std::max(max_excess, o.max_excess);
  excess_sum += o.excess_sum;
  changed_cells += o.changed_cells;
  max_reference_jump = std::max(max_reference_jump, o.max_reference_jump);
}

FrameJump frame_jump(std::span<const double> eps_k, std::span<const double> eps_k1, std::span<const double> ref_k,
                     std::span<const double> ref_k1) {
  FrameJump j;
  for (std::size_t c = 0; c < eps_k.size(); ++c) {
    const double dm = eps_k1[c] - eps_k[c], dr = ref_k1[c] - ref_k[c];
    const double excess = std::abs(dm) - std::abs(dr);
    j.max_excess = std::max(j.max_excess, excess);
    j.max_reference_jump = std::max(j.max_reference_jump, std::abs(dr));
    if (dm != 0 || dr != 0) {
      j.excess_sum += excess;
      ++j.changed_cells;
    }
  }
  return j;
}

}  // namespace vfe::apps

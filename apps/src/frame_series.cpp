#include "frame_series.hpp"

#include "command_output.hpp"
#include "dump_reader.hpp"

#include <glob.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <stdexcept>
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
  SeriesFrameCheck check;
  for (SceneParticles& p : series) {
    check.admit(p);
    check_coupling_velocities(c, p);
  }
  return series;
}

void SeriesFrameCheck::admit(SceneParticles& p) {
  if (!first_) first_ = FirstFrame{!p.ids.empty(), p.n, p.timestep, p.source_name};
  if (p.ids.empty() == first_->has_ids)
    throw DumpError(p.source_name + ": timestep " + std::to_string(p.timestep) + (p.ids.empty() ? " has no" : " has an") +
                    " id column and the series' first frame (" + first_->source_name +
                    ") does not; dump every frame with the same columns");
  if (!p.ids.empty()) {
    order_by_id(p);
  } else if (p.n != first_->n) {
    throw DumpError(p.source_name + ": timestep " + std::to_string(p.timestep) + " has " + std::to_string(p.n) +
                    " particles, the series' first frame (" + first_->source_name + ", timestep " +
                    std::to_string(first_->timestep) + ") has " + std::to_string(first_->n) +
                    "; without an id column particles cannot be matched between frames: dump the ids too");
  }
}

namespace {

/// Every frame of the dumps, loaded and ordered before the first is handed out.
class FileFrames final : public FrameSource {
 public:
  explicit FileFrames(const SceneConfig& c) : frames_(load_frame_series(c)) {}
  bool next(SceneParticles& frame) override {
    if (next_ >= frames_.size()) return false;
    frame = std::move(frames_[next_++]);
    return true;
  }
  std::int64_t count() const override { return static_cast<std::int64_t>(frames_.size()); }
  std::string description() const override { return std::to_string(frames_.size()) + " frame(s) from dump files"; }

 private:
  std::vector<SceneParticles> frames_;
  std::size_t next_ = 0;
};

/// The frames a command prints, each handed out as soon as its last atom line has come.
class CommandFrames final : public FrameSource {
 public:
  explicit CommandFrames(const SceneConfig& c)
      : config_(c),
        spec_(*c.series),
        shape_volumes_(config_shape_volumes(c)),
        output_(spec_.command, spec_.command_folder),
        name_("command '" + spec_.command + "'"),
        reader_(output_.stream(), "the output of " + name_) {}

  bool next(SceneParticles& frame) override {
    if (done_) return false;
    DumpFrame f;
    for (;;) {
      bool got = false;
      try {
        got = reader_.next(f);
      } catch (const DumpError& e) {
        done_ = true;
        output_.stop();
        throw DumpError(std::string(e.what()) + " (" + after() + ")");
      }
      if (!got) return finish();
      if (last_timestep_ && f.timestep <= *last_timestep_) {
        done_ = true;
        output_.stop();
        throw DumpError(name_ + ": printed timestep " + std::to_string(f.timestep) + " after timestep " +
                        std::to_string(*last_timestep_) + "; a live source must print its frames in time order, "
                        "one per timestep (" + after() + ")");
      }
      last_timestep_ = f.timestep;
      if ((spec_.from_timestep && f.timestep < *spec_.from_timestep) ||
          (spec_.to_timestep && f.timestep > *spec_.to_timestep))
        continue;
      const std::int64_t index = kept_++;
      if (index < spec_.first_frame) continue;
      frame = particles_from_dump(config_, std::move(f), spec_.command, shape_volumes_);
      frame.source_name = name_;
      check_.admit(frame);
      check_coupling_velocities(config_, frame);
      ++delivered_;
      // The frames asked for are in: the command is not needed any more.
      if (spec_.last_frame >= 0 && index >= spec_.last_frame) {
        done_ = true;
        output_.stop();
      }
      return true;
    }
  }
  std::int64_t count() const override { return -1; }
  std::string description() const override {
    return name_ + " (in " + (spec_.command_folder.empty() ? std::string(".") : spec_.command_folder.string()) + ")";
  }

 private:
  std::string after() const {
    return delivered_ == 0 ? "before any complete frame"
                           : "after " + std::to_string(delivered_) + " complete frame(s), which were computed";
  }

  /// At the end of the output: the command must have ended well and printed a frame.
  bool finish() {
    done_ = true;
    const std::string how = output_.wait();
    if (!how.empty()) throw std::runtime_error(name_ + " " + how + " (" + after() + ")");
    if (delivered_ == 0)
      throw DumpError(name_ + ": ended without printing a frame" +
                      (kept_ > 0 || last_timestep_ ? std::string(" in the timesteps and frames asked for") : "") +
                      "; it must print LIGGGHTS/LAMMPS text dump frames (ITEM: TIMESTEP ...) on its standard "
                      "output, e.g. vfe_liggghts --dump -");
    return false;
  }

  const SceneConfig& config_;
  FrameSeriesSpec spec_;
  std::vector<double> shape_volumes_;
  CommandOutput output_;
  std::string name_;
  DumpReader reader_;
  SeriesFrameCheck check_;
  std::optional<std::int64_t> last_timestep_;
  std::int64_t kept_ = 0, delivered_ = 0;
  bool done_ = false;
};

}  // namespace

std::unique_ptr<FrameSource> open_frame_source(const SceneConfig& c) {
  if (!c.series) throw ConfigError(c.source.string() + ": the particles are not a series of frames");
  if (!c.series->command.empty()) return std::make_unique<CommandFrames>(c);
  return std::make_unique<FileFrames>(c);
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

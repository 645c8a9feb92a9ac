// A scene's particles as a series of dump frames (globs or lists of dumps, or every frame
// of one dump) in timestep order, and the frame-to-frame jump of a method's void fraction
// against the reference's (docs/streams.md, "Jumps between frames").
#pragma once

#include "config.hpp"
#include "scene_particles.hpp"

#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace vfe::apps {

/// The dump files of a series: each glob expanded (matches in name order), each plain path
/// kept. Throws ConfigError naming the pattern when a glob matches nothing or a path does
/// not exist.
std::vector<std::filesystem::path> series_files(const FrameSeriesSpec& series, const std::string& source);

/// Every frame of the series' files in TIMESTEP order, kept by the spec's timesteps and
/// frames ranges. With an id column each frame's particles are ordered by id (so particle i
/// is the same particle in every frame, as incremental=1 and orientation=random need);
/// without one, every frame must hold as many particles as the first. Throws DumpError or
/// ConfigError naming the file (and the timestep) at fault: two frames with one timestep, a
/// repeated id, a count that changes without ids, no frame left by the ranges.
std::vector<SceneParticles> load_frame_series(const SceneConfig& config);

/// The checks every frame of a series passes, in series order: the same columns as the
/// first frame; with ids, particles put in id order (a repeated id is an error); without,
/// as many particles as the first frame. Throws DumpError naming the frame's source.
class SeriesFrameCheck {
 public:
  void admit(SceneParticles& frame);

 private:
  struct FirstFrame {
    bool has_ids;
    std::int64_t n, timestep;
    std::string source_name;
  };
  std::optional<FirstFrame> first_;
};

/// The frames of a series one at a time, in timestep order: every frame of the dumps
/// (load_frame_series), or the frames a command prints on its standard output, each handed
/// out as soon as it is complete (the command runs in the config's folder).
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// The next frame, checked as SeriesFrameCheck and (coupling) for velocities; false after
  /// the last. Throws DumpError, ConfigError or std::runtime_error naming the dump or the
  /// command and what went wrong: a frame cut short, a command that failed or printed no
  /// frame, timesteps out of order.
  virtual bool next(SceneParticles& frame) = 0;
  /// How many frames there are, or -1 when that is known only at the end (a command).
  virtual std::int64_t count() const = 0;
  /// Where the frames come from, for the log.
  virtual std::string description() const = 0;
};

/// The series' source: its dumps, or its command (started here). Throws as FrameSource.
std::unique_ptr<FrameSource> open_frame_source(const SceneConfig& config);

/// A frame's time: timestep * dem_dt, or the timestep when dem_dt is 0 (not given).
double frame_time(std::int64_t timestep, double dem_dt);

/// The jump of one method's void fraction between two frames against the reference's, per
/// cell deps = eps(k+1) - eps(k) and excess = |deps_method| - |deps_reference|. Pairs add up:
/// the max over all their cells, the mean over the cells where either field changed.
struct FrameJump {
  double max_excess = -std::numeric_limits<double>::infinity();  ///< over every cell
  double excess_sum = 0;             ///< over the changed cells
  std::int64_t changed_cells = 0;    ///< cells where the method's or the reference's eps changed
  double max_reference_jump = 0;     ///< max |deps_reference|

  /// excess_sum / changed_cells (0 when no cell changed).
  double mean_excess() const;
  /// Adds another pair (or series) of frames.
  void add(const FrameJump& other);
};

/// The jump between frames k and k + 1 of a method (eps_k, eps_k1) against the reference
/// (ref_k, ref_k1); all four spans hold one value per cell.
FrameJump frame_jump(std::span<const double> eps_k, std::span<const double> eps_k1, std::span<const double> ref_k,
                     std::span<const double> ref_k1);

}  // namespace vfe::apps

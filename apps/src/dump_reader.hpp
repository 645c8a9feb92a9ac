// LIGGGHTS/LAMMPS text dump reader (plain or gzip), columns mapped by header name.
#pragma once

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace vfe::apps {

/// Bad or unreadable dump. The message names the file, the line (when there is one), what
/// was wrong and how to fix it.
class DumpError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One frame of a dump as SoA arrays.
struct DumpFrame {
  std::int64_t timestep = 0;
  std::int64_t n = 0;
  /// BOX BOUNDS: xlo xhi ylo yhi zlo zhi (for triclinic boxes, the bounding box as written).
  std::array<double, 6> box{0, 0, 0, 0, 0, 0};
  /// Boundary flags of the BOX BOUNDS line ("ff ff ff", "pp pp fm", ...).
  std::string box_flags;
  bool triclinic = false;
  std::vector<double> centres;       ///< 3n, packed x y z
  std::vector<double> radii;         ///< n
  std::vector<double> orientations;  ///< 4n quaternions (w, x, y, z), or empty
  std::vector<std::int64_t> ids;     ///< n, or empty without an id column
  std::vector<std::int32_t> types;   ///< n, or empty without a type column
  std::vector<std::int32_t> shapes;  ///< n, or empty without a shape column (an integer per particle)
  std::vector<double> velocities;    ///< 3n, or empty without vx vy vz
  /// The ATOMS header's column names, in file order.
  std::vector<std::string> columns;
  /// Line of the frame's "ITEM: TIMESTEP" (1-based).
  std::int64_t first_line = 0;

  /// Zero-copy view for Engine::compute (orientations included when present).
  vfe::ParticleView view() const;
  /// Sum of the spheres' volumes 4/3 pi r^3.
  double total_volume() const;
  /// Mean diameter (0 when empty).
  double mean_diameter() const;
};

/// Which frame to read.
struct FrameSelector {
  /// 0-based index; negative counts from the end (-1 = last frame).
  std::int64_t index = -1;
};

/// Streaming reader: one frame at a time, in file order. Numbers are parsed whole; a frame
/// with fewer atom lines than its NUMBER OF ATOMS, or a last line that ends without a line
/// end right after a value (cut while the dump was being written), is an error.
class DumpReader {
 public:
  /// Opens the file (plain or gzip); throws DumpError if it cannot be read.
  explicit DumpReader(std::string path);
  /// Reads plain text frames from an open stream (a pipe: each frame is returned as soon as
  /// its last atom line has arrived), which the reader does not close; name stands for the
  /// stream in messages.
  DumpReader(std::FILE* stream, std::string name);
  ~DumpReader();
  DumpReader(const DumpReader&) = delete;
  DumpReader& operator=(const DumpReader&) = delete;

  /// Reads the next frame into frame; false at the end of the file. Throws DumpError.
  bool next(DumpFrame& frame);
  /// Skips the next frame without parsing its atom lines; false at the end of the file.
  bool skip();
  const std::string& path() const { return path_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
};

/// Reads one frame (default: the last one). Throws DumpError if the file has no such frame.
DumpFrame read_dump_frame(const std::string& path, FrameSelector which = {});
/// Reads every frame of the file.
std::vector<DumpFrame> read_dump(const std::string& path);

}  // namespace vfe::apps

#include "dump_reader.hpp"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <string_view>
#include <system_error>

namespace vfe::apps {

namespace {

constexpr std::string_view kFixHint =
    "write the dump with LIGGGHTS/LAMMPS `dump ID all custom N FILE id type x y z radius ...`";

std::string_view trim(std::string_view s) {
  std::size_t b = 0, e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t' || s[b] == '\r' || s[b] == '\n')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r' || s[e - 1] == '\n')) --e;
  return s.substr(b, e - b);
}

bool starts_with(std::string_view s, std::string_view p) { return s.substr(0, p.size()) == p; }

/// Splits on blanks (spaces, tabs); the trailing blank of dump lines is ignored.
void split(std::string_view s, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  const std::size_t n = s.size();
  while (i < n) {
    while (i < n && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\n')) ++i;
    if (i >= n) break;
    std::size_t j = i;
    while (j < n && s[j] != ' ' && s[j] != '\t' && s[j] != '\r' && s[j] != '\n') ++j;
    out.push_back(s.substr(i, j - i));
    i = j;
  }
}

std::optional<double> parse_double(std::string_view t) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  double v = 0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (r.ec != std::errc() || r.ptr != t.data() + t.size()) return std::nullopt;
  return v;
}

std::optional<std::int64_t> parse_int(std::string_view t) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  std::int64_t v = 0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (r.ec != std::errc() || r.ptr != t.data() + t.size()) {
    // Some writers print integer columns as floating point ("12.0", "1e3").
    const auto d = parse_double(t);
    if (d && std::isfinite(*d) && *d == std::floor(*d) && std::abs(*d) < 9.0e15)
      return static_cast<std::int64_t>(*d);
    return std::nullopt;
  }
  return v;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) {
    if (!s.empty()) s += ' ';
    s += x;
  }
  return s;
}

}  // namespace

struct DumpReader::Impl {
  std::string path;
  gzFile file = nullptr;
  std::FILE* stream = nullptr;  // instead of file: plain text from a stream this reader does not own
  std::string line;
  std::int64_t line_no = 0;  // number of the line in `line`
  bool pending = false;      // `line` was peeked and not yet consumed
  bool at_eof = false;
  std::vector<char> buffer = std::vector<char>(1 << 16);
  std::vector<std::string_view> tokens;

  ~Impl() {
    if (file) gzclose(file);
  }

  [[noreturn]] void fail(std::int64_t at_line, const std::string& what) const {
    if (at_line > 0)
      throw DumpError(path + ":" + std::to_string(at_line) + ": " + what);
    throw DumpError(path + ": " + what);
  }

  /// The gzip stream reports an error (not the end of the file).
  bool read_failed() const {
    int errnum = Z_OK;
    gzerror(file, &errnum);
    return errnum != Z_OK && errnum != Z_STREAM_END;
  }

  /// What the last read failure was.
  std::string read_error() const {
    if (stream) return std::strerror(errno);
    int errnum = Z_OK;
    const char* msg = gzerror(file, &errnum);
    if (errnum == Z_ERRNO) return std::strerror(errno);
    return msg && *msg ? msg : "read error";
  }

  /// Reads one physical line into `line`; false at the end of the file.
  bool read_line() {
    if (pending) {
      pending = false;
      return true;
    }
    if (at_eof) return false;
    line.clear();
    bool got = false;
    for (;;) {
      char* r = stream ? std::fgets(buffer.data(), static_cast<int>(buffer.size()), stream)
                       : gzgets(file, buffer.data(), static_cast<int>(buffer.size()));
      if (!r) {
        if (stream ? std::ferror(stream) != 0 : read_failed())
          fail(line_no + 1, "cannot read past this line (" + read_error() +
                                "); the file is truncated or damaged: re-write it, or for a "
                                "gzip file check it with `gzip -t`");
        at_eof = true;
        break;
      }
      got = true;
      const std::size_t len = std::strlen(r);
      line.append(r, len);
      if (len > 0 && r[len - 1] == '\n') break;
      if (len + 1 < buffer.size()) {
        // Last line without a newline: the read stops at the end of the file.
        if (stream ? std::feof(stream) != 0 : gzeof(file) != 0) break;
      }
    }
    if (!got) return false;
    if (line.empty() || line.back() != '\n') {
      // A last line without a line end: complete, unless the gzip stream was cut short.
      if (!stream && read_failed())
        fail(line_no + 1, "the file ends in the middle of this line (" + read_error() +
                              "); the file is truncated or damaged: re-write it, or for a gzip file "
                              "check it with `gzip -t`");
      // LIGGGHTS ends every line with a blank, LAMMPS with a line end: a last line that
      // stops right after a character was cut inside its last value (a dump still being
      // written), whose digits may be missing.
      const char last = line.empty() ? ' ' : line.back();
      if (last != ' ' && last != '\t' && last != '\r')
        fail(line_no + 1, "the file ends inside this line, right after '" + line.substr(line.size() - std::min<std::size_t>(line.size(), 20)) +
                              "' (no line end): its last value may be cut short, as in a dump still "
                              "being written; wait until the dump is complete, or end the line if it is");
    }
    ++line_no;
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    return true;
  }

  /// Next line that is not blank; false at the end of the file.
  bool read_nonblank() {
    while (read_line())
      if (!trim(line).empty()) return true;
    return false;
  }

  std::string value_line(std::string_view item) {
    if (!read_line())
      fail(line_no, "the file ends right after 'ITEM: " + std::string(item) +
                        "' (its value line is missing); the file is truncated");
    return line;
  }

  std::int64_t int_value(std::string_view item, std::int64_t min_value) {
    const std::string v = value_line(item);
    const auto t = trim(v);
    const auto x = parse_int(t);
    if (!x || *x < min_value)
      fail(line_no, "the value of 'ITEM: " + std::string(item) + "' is '" + std::string(t) +
                        "', expected an integer >= " + std::to_string(min_value));
    return *x;
  }

  struct Header {
    std::int64_t timestep = 0;
    std::int64_t n = -1;
    bool has_box = false;
    std::array<double, 6> box{0, 0, 0, 0, 0, 0};
    std::string box_flags;
    bool triclinic = false;
    std::vector<std::string> columns;
    std::int64_t first_line = 0;
    std::int64_t atoms_line = 0;
  };

  /// Reads the items of one frame up to and including its ATOMS header. False at the end
  /// of the file (no more frames).
  bool read_header(Header& h) {
    if (!read_nonblank()) return false;
    h = Header{};
    h.first_line = line_no;
    if (!starts_with(trim(line), "ITEM:"))
      fail(line_no, "expected 'ITEM: TIMESTEP' at the start of a frame, found '" +
                        std::string(trim(line)).substr(0, 60) +
                        "'; this is not a LIGGGHTS/LAMMPS text dump, or the previous frame has "
                        "more atom lines than its NUMBER OF ATOMS says");
    bool have_timestep = false;
    for (bool first = true;; first = false) {
      if (!first && !read_nonblank())
        fail(line_no, "the file ends inside the header of the frame that starts at line " +
                          std::to_string(h.first_line) +
                          " (no 'ITEM: ATOMS' line); the file is truncated");
      const std::string_view t = trim(line);
      if (!starts_with(t, "ITEM:"))
        fail(line_no, "expected an 'ITEM: ...' line in the frame header, found '" +
                          std::string(t).substr(0, 60) + "'");
      const std::string_view item = trim(t.substr(5));
      if (starts_with(item, "TIMESTEP")) {
        if (have_timestep)
          fail(line_no, "a second 'ITEM: TIMESTEP' before 'ITEM: ATOMS' of the frame that starts "
                        "at line " + std::to_string(h.first_line) + "; the previous frame is incomplete");
        h.timestep = int_value("TIMESTEP", std::numeric_limits<std::int64_t>::min());
        have_timestep = true;
      } else if (starts_with(item, "NUMBER OF ATOMS")) {
        h.n = int_value("NUMBER OF ATOMS", 0);
      } else if (starts_with(item, "BOX BOUNDS")) {
        std::vector<std::string_view> f;
        split(item.substr(10), f);
        std::vector<std::string> flags;
        for (auto x : f) {
          if (x == "xy" || x == "xz" || x == "yz")
            h.triclinic = true;
          else
            flags.emplace_back(x);
        }
        h.box_flags = join(flags);
        for (int d = 0; d < 3; ++d) {
          if (!read_line())
            fail(line_no, "the file ends inside 'ITEM: BOX BOUNDS' (3 lines of bounds expected); "
                          "the file is truncated");
          split(line, tokens);
          const std::size_t want = h.triclinic ? 3 : 2;
          if (tokens.size() != want)
            fail(line_no, "BOX BOUNDS line has " + std::to_string(tokens.size()) + " values, expected " +
                              std::to_string(want) + " (lo hi" + (h.triclinic ? " tilt" : "") + ")");
          for (int k = 0; k < 2; ++k) {
            const auto v = parse_double(tokens[static_cast<std::size_t>(k)]);
            if (!v || !std::isfinite(*v))
              fail(line_no, "BOX BOUNDS value '" + std::string(tokens[static_cast<std::size_t>(k)]) +
                                "' is not a finite number");
            h.box[static_cast<std::size_t>(2 * d + k)] = *v;
          }
        }
        h.has_box = true;
      } else if (starts_with(item, "ATOMS")) {
        h.atoms_line = line_no;
        std::vector<std::string_view> c;
        split(item.substr(5), c);
        h.columns.assign(c.begin(), c.end());
        if (!have_timestep)
          fail(line_no, "'ITEM: ATOMS' without a preceding 'ITEM: TIMESTEP' in this frame");
        if (h.n < 0)
          fail(line_no, "'ITEM: ATOMS' without a preceding 'ITEM: NUMBER OF ATOMS' in this frame");
        return true;
      } else if (starts_with(item, "UNITS") || starts_with(item, "TIME")) {
        value_line(item);  // dump_modify units/time yes: one value line, not needed here
      } else {
        fail(line_no, "unknown item '" + std::string(t) +
                          "'; expected TIMESTEP, NUMBER OF ATOMS, BOX BOUNDS or ATOMS (only text "
                          "dumps of style custom/atom are supported)");
      }
    }
  }

  /// Consumes the next atom line of a frame, or fails with a truncation message.
  void atom_line(const Header& h, std::int64_t k) {
    if (!read_line())
      fail(line_no, "the file ends after " + std::to_string(k) + " of " + std::to_string(h.n) +
                        " atom lines of the frame at timestep " + std::to_string(h.timestep) +
                        " (its ATOMS header is at line " + std::to_string(h.atoms_line) +
                        "); the file is truncated: was the dump still being written? Use a "
                        "complete file or drop the incomplete last frame");
    if (starts_with(trim(line), "ITEM:"))
      fail(line_no, "found '" + std::string(trim(line)) + "' after only " + std::to_string(k) +
                        " of " + std::to_string(h.n) + " atom lines of the frame at timestep " +
                        std::to_string(h.timestep) +
                        "; the frame is truncated or its NUMBER OF ATOMS is wrong");
  }
};

DumpReader::DumpReader(std::string path) : impl_(std::make_unique<Impl>()), path_(std::move(path)) {
  impl_->path = path_;
  std::error_code ec;
  if (std::filesystem::is_directory(path_, ec))
    throw DumpError(path_ + ": is a folder, not a dump file; give the path of a LIGGGHTS/LAMMPS "
                            "text dump (plain or .gz)");
  if (!std::filesystem::exists(path_, ec))
    throw DumpError(path_ + ": no such file; check the path (a config's paths are relative to "
                            "the config file's folder)");
  errno = 0;
  impl_->file = gzopen(path_.c_str(), "rb");
  if (!impl_->file) {
    const std::string why = errno ? std::strerror(errno) : "out of memory";
    throw DumpError(path_ + ": cannot open the file (" + why + "); check that it exists and is readable");
  }
  gzbuffer(impl_->file, 1 << 17);
}

DumpReader::DumpReader(std::FILE* stream, std::string name) : impl_(std::make_unique<Impl>()), path_(std::move(name)) {
  impl_->path = path_;
  impl_->stream = stream;
}

DumpReader::~DumpReader() = default;

bool DumpReader::skip() {
  Impl::Header h;
  if (!impl_->read_header(h)) return false;
  for (std::int64_t k = 0; k < h.n; ++k) impl_->atom_line(h, k);
  return true;
}

bool DumpReader::next(DumpFrame& frame) {
  Impl& s = *impl_;
  Impl::Header h;
  if (!s.read_header(h)) return false;

  const auto& cols = h.columns;
  auto find = [&](std::initializer_list<std::string_view> names) -> int {
    for (auto name : names)
      for (std::size_t i = 0; i < cols.size(); ++i)
        if (cols[i] == name) return static_cast<int>(i);
    return -1;
  };
  const std::string have = "the ATOMS header has '" + join(cols) + "'";

  // Positions: plain, unwrapped, scaled or scaled unwrapped (the first found, in that order).
  int pos[3] = {-1, -1, -1};
  bool scaled = false;
  {
    const char* sets[4][3] = {{"x", "y", "z"}, {"xu", "yu", "zu"}, {"xs", "ys", "zs"}, {"xsu", "ysu", "zsu"}};
    for (int set = 0; set < 4 && pos[0] < 0; ++set) {
      const int a = find({sets[set][0]}), b = find({sets[set][1]}), c = find({sets[set][2]});
      if (a >= 0 && b >= 0 && c >= 0) {
        pos[0] = a, pos[1] = b, pos[2] = c;
        scaled = set >= 2;
      }
    }
  }
  if (pos[0] < 0)
    s.fail(h.atoms_line, "no position columns: " + have +
                             ", which lacks x y z (or xs ys zs, xu yu zu); " + std::string(kFixHint));
  const int col_radius = find({"radius"});
  const int col_diameter = col_radius < 0 ? find({"diameter"}) : -1;
  if (col_radius < 0 && col_diameter < 0)
    s.fail(h.atoms_line, "no radius column: " + have + ", which lacks 'radius' (or 'diameter'); " +
                             std::string(kFixHint));
  const int col_id = find({"id"});
  const int col_type = find({"type"});
  const int col_shape = find({"shape"});
  int vel[3] = {find({"vx"}), find({"vy"}), find({"vz"})};
  const bool has_vel = vel[0] >= 0 && vel[1] >= 0 && vel[2] >= 0;
  int quat[4] = {find({"quatw"}), find({"quati"}), find({"quatj"}), find({"quatk"})};
  if (quat[0] < 0 || quat[1] < 0 || quat[2] < 0 || quat[3] < 0) {
    const int q[4] = {find({"q1"}), find({"q2"}), find({"q3"}), find({"q4"})};
    std::copy(q, q + 4, quat);
  }
  const bool has_quat = quat[0] >= 0 && quat[1] >= 0 && quat[2] >= 0 && quat[3] >= 0;

  if (scaled && !h.has_box)
    s.fail(h.atoms_line, "scaled coordinates (xs ys zs) need 'ITEM: BOX BOUNDS' in the frame header");
  if (scaled && h.triclinic)
    s.fail(h.atoms_line, "scaled coordinates in a triclinic box are not supported; dump x y z instead");

  frame = DumpFrame{};
  frame.timestep = h.timestep;
  frame.n = h.n;
  frame.box = h.box;
  frame.box_flags = h.box_flags;
  frame.triclinic = h.triclinic;
  frame.columns = cols;
  frame.first_line = h.first_line;
  const auto n = static_cast<std::size_t>(h.n);
  const std::size_t cap = std::min<std::size_t>(n, std::size_t{1} << 20);  // n may be bogus: grow past it as lines come
  frame.centres.reserve(3 * cap);
  frame.radii.reserve(cap);
  if (has_quat) frame.orientations.reserve(4 * cap);
  if (col_id >= 0) frame.ids.reserve(cap);
  if (col_type >= 0) frame.types.reserve(cap);
  if (col_shape >= 0) frame.shapes.reserve(cap);
  if (has_vel) frame.velocities.reserve(3 * cap);

  const std::size_t ncols = cols.size();
  auto number = [&](int col, const char* what) -> double {
    const std::string_view t = s.tokens[static_cast<std::size_t>(col)];
    const auto v = parse_double(t);
    if (!v)
      s.fail(s.line_no, "column '" + cols[static_cast<std::size_t>(col)] + "' (" + what + ") has the value '" +
                            std::string(t) + "', which is not a number; fix or re-write this line");
    return *v;
  };
  auto finite = [&](int col, const char* what) -> double {
    const double v = number(col, what);
    if (!std::isfinite(v))
      s.fail(s.line_no, "column '" + cols[static_cast<std::size_t>(col)] + "' (" + what + ") is '" +
                            std::string(s.tokens[static_cast<std::size_t>(col)]) +
                            "', expected a finite number");
    return v;
  };

  for (std::int64_t k = 0; k < h.n; ++k) {
    s.atom_line(h, k);
    split(s.line, s.tokens);
    if (s.tokens.size() != ncols)
      s.fail(s.line_no, "atom line has " + std::to_string(s.tokens.size()) + " values, expected " +
                            std::to_string(ncols) + " (one per column of the ATOMS header '" + join(cols) +
                            "'); the line is cut short or damaged");
    double c[3];
    for (int d = 0; d < 3; ++d) {
      c[d] = finite(pos[d], "position");
      if (scaled) c[d] = h.box[2 * d] + c[d] * (h.box[2 * d + 1] - h.box[2 * d]);
    }
    frame.centres.insert(frame.centres.end(), c, c + 3);
    double r = col_radius >= 0 ? finite(col_radius, "radius") : 0.5 * finite(col_diameter, "diameter");
    if (!(r > 0))
      s.fail(s.line_no, std::string(col_radius >= 0 ? "radius" : "diameter") + " is '" +
                            std::string(s.tokens[static_cast<std::size_t>(col_radius >= 0 ? col_radius : col_diameter)]) +
                            "', expected a value > 0");
    frame.radii.push_back(r);
    if (has_quat)
      for (int d = 0; d < 4; ++d) frame.orientations.push_back(finite(quat[d], "orientation"));
    if (col_id >= 0) {
      const auto v = parse_int(s.tokens[static_cast<std::size_t>(col_id)]);
      if (!v)
        s.fail(s.line_no, "column 'id' has the value '" + std::string(s.tokens[static_cast<std::size_t>(col_id)]) +
                              "', which is not an integer");
      frame.ids.push_back(*v);
    }
    auto int32_column = [&](int col, const char* name) {
      const auto v = parse_int(s.tokens[static_cast<std::size_t>(col)]);
      if (!v || *v < std::numeric_limits<std::int32_t>::min() || *v > std::numeric_limits<std::int32_t>::max())
        s.fail(s.line_no, std::string("column '") + name + "' has the value '" +
                              std::string(s.tokens[static_cast<std::size_t>(col)]) + "', which is not an integer");
      return static_cast<std::int32_t>(*v);
    };
    if (col_type >= 0) frame.types.push_back(int32_column(col_type, "type"));
    if (col_shape >= 0) frame.shapes.push_back(int32_column(col_shape, "shape"));
    if (has_vel)
      for (int d = 0; d < 3; ++d) frame.velocities.push_back(number(vel[d], "velocity"));
  }
  return true;
}

vfe::ParticleView DumpFrame::view() const {
  vfe::ParticleView v;
  v.n = n;
  v.centres = centres.data();
  v.radii = radii.data();
  v.orientations = orientations.empty() ? nullptr : orientations.data();
  return v;
}

double DumpFrame::total_volume() const {
  double s = 0;
  for (double r : radii) s += r * r * r;
  return 4.0 / 3.0 * std::numbers::pi * s;
}

double DumpFrame::mean_diameter() const {
  if (radii.empty()) return 0;
  double s = 0;
  for (double r : radii) s += 2 * r;
  return s / static_cast<double>(radii.size());
}

DumpFrame read_dump_frame(const std::string& path, FrameSelector which) {
  DumpReader reader(path);
  DumpFrame frame;
  if (which.index >= 0) {
    for (std::int64_t i = 0; i < which.index; ++i)
      if (!reader.skip())
        throw DumpError(path + ": has only " + std::to_string(i) + " frame(s), frame " +
                        std::to_string(which.index) + " (0-based) was asked for; choose a smaller frame index");
    if (!reader.next(frame))
      throw DumpError(path + ": has only " + std::to_string(which.index) + " frame(s), frame " +
                      std::to_string(which.index) + " (0-based) was asked for; choose a smaller frame index");
    return frame;
  }
  // From the end: count the frames with a cheap pass, then read the one asked for.
  std::int64_t count = 0;
  while (reader.skip()) ++count;
  const std::int64_t idx = count + which.index;
  if (count == 0)
    throw DumpError(path + ": contains no frame (empty file); expected a LIGGGHTS/LAMMPS text dump "
                           "starting with 'ITEM: TIMESTEP'");
  if (idx < 0)
    throw DumpError(path + ": has " + std::to_string(count) + " frame(s), frame " +
                    std::to_string(which.index) + " from the end was asked for");
  return read_dump_frame(path, FrameSelector{idx});
}

std::vector<DumpFrame> read_dump(const std::string& path) {
  DumpReader reader(path);
  std::vector<DumpFrame> frames;
  DumpFrame f;
  while (reader.next(f)) frames.push_back(std::move(f));
  return frames;
}

}  // namespace vfe::apps

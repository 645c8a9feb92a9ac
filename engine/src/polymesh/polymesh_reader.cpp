#include "polymesh/polymesh_reader.hpp"

#include <vfe/engine.hpp>

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <concepts>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>
#include <system_error>

namespace vfe {
namespace {

namespace fs = std::filesystem;

constexpr const char* kRegenerate =
    "regenerate the mesh (blockMesh, snappyHexMesh) or repair the file, then check it with checkMesh";

// Counts beyond this are corrupt (2^40 entries would need terabytes).
constexpr std::int64_t kMaxCount = std::int64_t(1) << 40;
constexpr std::int64_t kMaxUniformPoints = std::int64_t(1) << 16;

[[noreturn]] void io_error(const std::string& message) { throw Error(VFE_ERROR_IO, message); }

std::string read_plain(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) io_error("cannot open " + path.string() + " for reading; check that it exists and is readable");
  std::string text;
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  if (size < 0) io_error("cannot read " + path.string() + "; check that it is a regular, readable file");
  text.resize(static_cast<std::size_t>(size));
  in.seekg(0, std::ios::beg);
  if (size > 0 && !in.read(text.data(), size))
    io_error("reading " + path.string() + " failed after " + std::to_string(in.gcount()) + " of " +
             std::to_string(static_cast<long long>(size)) + " bytes; check the disk and the file");
  return text;
}

std::string read_gzip(const fs::path& path) {
  gzFile gz = gzopen(path.string().c_str(), "rb");
  if (gz == nullptr) io_error("cannot open " + path.string() + " for reading; check that it exists and is readable");
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const int got = gzread(gz, buffer, sizeof(buffer));
    if (got < 0) {
      int code = 0;
      const std::string why = gzerror(gz, &code);
      gzclose(gz);
      io_error("cannot decompress " + path.string() + " (" + why +
               "); the file is not valid gzip or is truncated: recompress it or write the mesh uncompressed");
    }
    if (got == 0) break;
    text.append(buffer, static_cast<std::size_t>(got));
  }
  // gzread returns 0 both at the end and when a gzip stream is cut short.
  int code = 0;
  const char* why = gzerror(gz, &code);
  if (code != Z_OK && code != Z_STREAM_END) {
    const std::string what = why;
    gzclose(gz);
    io_error("cannot decompress " + path.string() + " (" + what + "); recompress it or write the mesh uncompressed");
  }
  if (gzclose(gz) != Z_OK)
    io_error("cannot decompress " + path.string() +
             ": the gzip stream is truncated or damaged; recompress it or write the mesh uncompressed");
  return text;
}

/// The text of one polyMesh file, `name` or `name.gz` in dir.
struct FileText {
  fs::path path;
  std::string text;
};

FileText load(const fs::path& dir, const std::string& name) {
  std::error_code ec;
  const fs::path plain = dir / name;
  const fs::path gz = dir / (name + ".gz");
  if (fs::is_regular_file(plain, ec)) return {plain, read_plain(plain)};
  if (fs::is_regular_file(gz, ec)) return {gz, read_gzip(gz)};
  for (const fs::path& p : {plain, gz})
    if (fs::exists(p, ec))
      io_error("polyMesh file " + p.string() + " is not a regular file (a folder?); it must be the " + name +
               " file written by blockMesh or snappyHexMesh");
  io_error("polyMesh file '" + name + "' not found in " + dir.string() + " (looked for " + name + " and " + name +
           ".gz); give an OpenFOAM case folder (with constant/polyMesh) or its constant/polyMesh folder, which "
           "needs points, faces, owner, neighbour and boundary (written by blockMesh or snappyHexMesh)");
}

bool is_delimiter(char c) {
  return std::isspace(static_cast<unsigned char>(c)) || c == '(' || c == ')' || c == '{' || c == '}' || c == ';' ||
         c == '"' || c == ',' || c == '/';
}

/// Tokens of an OpenFOAM file: FoamFile header, comments, numbers, punctuation, words,
/// and raw binary blocks. Every failure names the file and the line (or byte).
class FoamText {
 public:
  explicit FoamText(FileText file) : path_(std::move(file.path)), text_(std::move(file.text)) { parse_header(); }

  bool binary() const { return binary_; }
  std::size_t label_bytes() const { return label_bytes_; }
  std::size_t scalar_bytes() const { return scalar_bytes_; }
  std::string header(const std::string& key) const {
    const auto it = header_.find(key);
    return it == header_.end() ? std::string() : it->second;
  }
  std::string file_name() const { return path_.string(); }
  std::size_t pos() const { return pos_; }
  /// Bytes left after the current position: an ASCII list of n entries of at least k bytes
  /// each cannot have more than remaining() / k entries, which bounds what to reserve.
  std::size_t remaining() const { return text_.size() - std::min(pos_, text_.size()); }

  [[noreturn]] void fail_at(std::size_t at, const std::string& what, const char* hint = kRegenerate) const {
    std::ostringstream msg;
    msg << path_.string() << ", ";
    if (binary_ && at > header_end_) {
      msg << "byte " << at;
    } else {
      const auto line = 1 + std::count(text_.begin(), text_.begin() + static_cast<std::ptrdiff_t>(std::min(at, text_.size())), '\n');
      msg << "line " << line;
    }
    msg << ": " << what;
    if (hint != nullptr && *hint != '\0') msg << "; " << hint;
    throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
  }
  [[noreturn]] void fail(const std::string& what, const char* hint = kRegenerate) {
    skip();
    fail_at(pos_, what, hint);
  }

  /// Skips white space and C/C++ comments.
  void skip() {
    const std::size_t n = text_.size();
    while (pos_ < n) {
      const char c = text_[pos_];
      if (std::isspace(static_cast<unsigned char>(c))) {
        ++pos_;
      } else if (c == '/' && pos_ + 1 < n && text_[pos_ + 1] == '/') {
        const std::size_t eol = text_.find('\n', pos_);
        pos_ = eol == std::string::npos ? n : eol + 1;
      } else if (c == '/' && pos_ + 1 < n && text_[pos_ + 1] == '*') {
        const std::size_t end = text_.find("*/", pos_ + 2);
        if (end == std::string::npos) fail_at(pos_, "comment opened with /* is never closed");
        pos_ = end + 2;
      } else {
        break;
      }
    }
  }
  /// Next significant character (0 at the end of the file).
  char peek() {
    skip();
    return pos_ < text_.size() ? text_[pos_] : '\0';
  }
  bool at_end() { return peek() == '\0'; }

  /// The next token as text, for messages.
  std::string describe_next() {
    skip();
    if (pos_ >= text_.size()) return "the end of the file";
    std::size_t end = pos_ + 1;
    if (!is_delimiter(text_[pos_]))
      while (end < text_.size() && end - pos_ < 24 && !is_delimiter(text_[end])) ++end;
    std::string token = text_.substr(pos_, end - pos_);
    for (char& ch : token)
      if (!std::isprint(static_cast<unsigned char>(ch))) ch = '?';
    return "'" + token + "'";
  }

  void expect(char c, const std::string& context) {
    if (peek() != c) fail(std::string("expected '") + c + "' " + context + " but found " + describe_next());
    ++pos_;
  }
  bool accept(char c) {
    if (peek() != c) return false;
    ++pos_;
    return true;
  }

  /// The next number-like token; ctx() names what is expected (only built on failure).
  template <std::invocable Ctx>
  std::string_view number_token(Ctx&& ctx, const char* kind) {
    skip();
    if (pos_ >= text_.size()) fail_at(pos_, "the file ends where " + ctx() + " (" + kind + ") should be: it is truncated");
    std::size_t end = pos_;
    while (end < text_.size() && !is_delimiter(text_[end])) ++end;
    if (end == pos_) fail(std::string("expected ") + kind + " for " + ctx() + " but found " + describe_next());
    return std::string_view(text_).substr(pos_, end - pos_);
  }

  template <std::invocable Ctx>
  std::int64_t label(Ctx&& ctx) {
    const std::string_view tok = number_token(ctx, "an integer");
    std::int64_t v = 0;
    const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc() || ptr != tok.data() + tok.size())
      fail(std::string("expected an integer for ") + ctx() + " but found " + describe_next());
    pos_ += tok.size();
    return v;
  }
  std::int64_t label(const std::string& context) {
    return label([&] { return context; });
  }

  template <std::invocable Ctx>
  double scalar(Ctx&& ctx) {
    const std::string_view tok = number_token(ctx, "a number");
    const char* first = tok.data();
    if (!tok.empty() && tok[0] == '+') ++first;  // from_chars does not take a leading '+'
    double v = 0;
    const auto [ptr, ec] = std::from_chars(first, tok.data() + tok.size(), v);
    if (ptr != tok.data() + tok.size() || (ec != std::errc() && ec != std::errc::result_out_of_range))
      fail(std::string("expected a number for ") + ctx() + " but found " + describe_next());
    if (!std::isfinite(v) || ec == std::errc::result_out_of_range)
      fail(ctx() + " is " + describe_next() + ", not a finite number");
    pos_ += tok.size();
    return v;
  }
  double scalar(const std::string& context) {
    return scalar([&] { return context; });
  }

  /// A word or a quoted string.
  std::string word(const std::string& context) {
    skip();
    if (pos_ >= text_.size()) fail_at(pos_, "the file ends where " + context + " should be: it is truncated");
    if (text_[pos_] == '"') {
      const std::size_t end = text_.find('"', pos_ + 1);
      if (end == std::string::npos) fail("string opened with \" is never closed");
      std::string s = text_.substr(pos_ + 1, end - pos_ - 1);
      pos_ = end + 1;
      return s;
    }
    std::size_t end = pos_;
    while (end < text_.size() && !is_delimiter(text_[end])) ++end;
    if (end == pos_) fail("expected " + context + " but found " + describe_next());
    std::string s = text_.substr(pos_, end - pos_);
    pos_ = end;
    return s;
  }

  /// The raw text of a dictionary entry's value up to its ';' (nested brackets kept).
  std::string entry_value(const std::string& key) {
    skip();
    const std::size_t start = pos_;
    int depth = 0;
    while (true) {
      skip();
      if (pos_ >= text_.size()) fail_at(start, "entry '" + key + "' is not closed with ';' before the end of the file");
      const char c = text_[pos_];
      if (c == '"') {
        const std::size_t end = text_.find('"', pos_ + 1);
        if (end == std::string::npos) fail("string opened with \" is never closed");
        pos_ = end + 1;
        continue;
      }
      if (c == '(' || c == '[') ++depth;
      if (c == ')' || c == ']') --depth;
      if (c == '}' && depth == 0) fail("entry '" + key + "' is not closed with ';'");
      if (c == ';' && depth <= 0) break;
      ++pos_;
    }
    std::string value = text_.substr(start, pos_ - start);
    ++pos_;  // ';'
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back()))) value.pop_back();
    if (value.size() >= 2 && value.front() == '"' && value.back() == '"') value = value.substr(1, value.size() - 2);
    return value;
  }

  /// Skips a balanced { ... } block (the '{' is next).
  void skip_block() {
    expect('{', "to open a sub-dictionary");
    int depth = 1;
    while (depth > 0) {
      skip();
      if (pos_ >= text_.size()) fail_at(pos_, "a sub-dictionary opened with '{' is never closed");
      const char c = text_[pos_++];
      if (c == '{') ++depth;
      if (c == '}') --depth;
      if (c == '"') {
        const std::size_t end = text_.find('"', pos_);
        if (end == std::string::npos) fail("string opened with \" is never closed");
        pos_ = end + 1;
      }
    }
  }

  /// Dictionary entries "key value;" up to the closing '}' (consumed). Sub-dictionaries are
  /// skipped; the values of primitive entries are returned as raw text.
  std::map<std::string, std::string> dictionary(const std::string& context) {
    std::map<std::string, std::string> entries;
    while (true) {
      const char c = peek();
      if (c == '}') {
        ++pos_;
        return entries;
      }
      if (c == '\0') fail_at(pos_, context + " is not closed with '}': the file is truncated");
      const std::string key = word("an entry name in " + context);
      if (peek() == '{') {
        skip_block();
        continue;
      }
      entries[key] = entry_value(key);
    }
  }

  /// The next `bytes` bytes of a binary block (pos_ must be just after its '(' or '{').
  const char* raw(std::size_t bytes, const std::string& context) {
    if (bytes > text_.size() - pos_)
      fail_at(pos_, context + " needs " + std::to_string(bytes) + " bytes of binary data but the file has only " +
                        std::to_string(text_.size() - pos_) + " left: it is truncated");
    const char* p = text_.data() + pos_;
    pos_ += bytes;
    return p;
  }
  /// Closing bracket right after a binary block.
  void expect_raw_end(char c, const std::string& context) {
    if (pos_ >= text_.size() || text_[pos_] != c)
      fail_at(pos_, std::string("expected '") + c + "' to close the binary data of " + context +
                        ": the count does not match the data or the file is damaged");
    ++pos_;
  }
  std::int64_t raw_label(const char* p) const {
    if (label_bytes_ == 4) {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    std::int64_t v;
    std::memcpy(&v, p, 8);
    return v;
  }
  double raw_scalar(const char* p) const {
    if (scalar_bytes_ == 4) {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    double v;
    std::memcpy(&v, p, 8);
    return v;
  }

  /// Only white space and comments may follow the data.
  void expect_end(const std::string& context) {
    if (!at_end()) fail("unexpected " + describe_next() + " after " + context);
  }

 private:
  void parse_header() {
    skip();
    if (text_.compare(pos_, 8, "FoamFile") == 0 && pos_ + 8 <= text_.size() &&
        (pos_ + 8 == text_.size() || is_delimiter(text_[pos_ + 8]))) {
      pos_ += 8;
      expect('{', "after FoamFile");
      header_ = dictionary("the FoamFile header");
    }
    header_end_ = pos_;
    const std::string format = header("format");
    if (format == "binary") {
      binary_ = true;
    } else if (!format.empty() && format != "ascii") {
      fail_at(0, "the FoamFile header says 'format " + format + ";', expected ascii or binary");
    }
    const std::string arch = header("arch");
    if (binary_ && arch.find("MSB") != std::string::npos)
      throw Error(VFE_ERROR_UNSUPPORTED,
                  path_.string() + ": big-endian (MSB) binary files are not supported; convert the mesh to ASCII with "
                                   "'foamFormatConvert -constant' after setting 'writeFormat ascii;' in "
                                   "system/controlDict");
    const auto size_of = [&](const char* key, std::size_t fallback) -> std::size_t {
      const std::size_t at = arch.find(key);
      if (at == std::string::npos) return fallback;
      const char* first = arch.data() + at + std::strlen(key);
      int bits = 0;
      std::from_chars(first, arch.data() + arch.size(), bits);
      if (bits != 32 && bits != 64)
        throw Error(VFE_ERROR_UNSUPPORTED,
                    path_.string() + ": arch '" + arch + "' has " + key + std::to_string(bits) +
                        " bits, only 32 and 64 are supported; convert the mesh to ASCII with 'foamFormatConvert "
                        "-constant' after setting 'writeFormat ascii;' in system/controlDict");
      return static_cast<std::size_t>(bits / 8);
    };
    label_bytes_ = size_of("label=", 4);
    scalar_bytes_ = size_of("scalar=", 8);
  }

  fs::path path_;
  std::string text_;
  std::size_t pos_ = 0;
  std::size_t header_end_ = 0;
  std::map<std::string, std::string> header_;
  bool binary_ = false;
  std::size_t label_bytes_ = 4;
  std::size_t scalar_bytes_ = 8;
};

/// Reads the count of a list ("N" before its opening bracket), or -1 when the list has none.
std::int64_t list_count(FoamText& t, const std::string& what) {
  const char c = t.peek();
  if (c == '(') return -1;
  if (c == '\0') t.fail_at(t.pos(), "the file ends where " + what + " should start: it is truncated");
  const std::size_t at = t.pos();
  const std::int64_t n = t.label([&] { return "the size of " + what; });
  if (n < 0 || n > kMaxCount) t.fail_at(at, what + " has the impossible size " + std::to_string(n));
  return n;
}

/// Reads a list of labels ("N(a b c)", "(a b c)", "N{a}", or their binary forms), appends
/// it to out and returns its length. check(value, index, pos) validates each label.
template <class Check>
std::int64_t read_label_list(FoamText& t, std::vector<std::int64_t>& out, const std::string& what,
                             std::int64_t max_uniform, Check&& check) {
  const std::int64_t n = list_count(t, what);
  const char open = t.peek();
  const std::size_t list_at = t.pos();
  if (open == '{') {
    t.expect('{', "");
    if (n > max_uniform)
      t.fail_at(list_at, what + " is a uniform list of " + std::to_string(n) + " entries, more than the " +
                             std::to_string(max_uniform) + " it can have");
    std::int64_t v;
    const std::size_t at = t.pos();
    if (t.binary()) {
      v = t.raw_label(t.raw(t.label_bytes(), what));
      t.expect_raw_end('}', what);
    } else {
      v = t.label("the value of " + what);
      t.expect('}', "to close the uniform list " + what);
    }
    for (std::int64_t i = 0; i < n; ++i) check(v, i, at);
    out.insert(out.end(), static_cast<std::size_t>(n), v);
    return n;
  }
  if (open != '(') {
    if (t.binary() && n == 0) return 0;  // binary writers omit the brackets of empty lists
    t.fail("expected '(' to open " + what + " but found " + t.describe_next());
  }
  t.expect('(', "");
  if (t.binary() && n >= 0) {
    const std::size_t at = t.pos();
    const char* p = t.raw(static_cast<std::size_t>(n) * t.label_bytes(), what);
    out.reserve(out.size() + static_cast<std::size_t>(n));
    for (std::int64_t i = 0; i < n; ++i) {
      const std::int64_t v = t.raw_label(p + static_cast<std::size_t>(i) * t.label_bytes());
      check(v, i, at + static_cast<std::size_t>(i) * t.label_bytes());
      out.push_back(v);
    }
    t.expect_raw_end(')', what);
    return n;
  }
  std::int64_t i = 0;
  while (true) {
    const char c = t.peek();
    if (c == ')') {
      if (n >= 0 && i < n)
        t.fail(what + " ends after " + std::to_string(i) + " entries but its count says " + std::to_string(n) +
               ": the list is truncated or its count is wrong");
      t.expect(')', "");
      return i;
    }
    if (c == '\0')
      t.fail_at(t.pos(), "the file ends inside " + what + " after " + std::to_string(i) + " entries: it is truncated");
    if (n >= 0 && i == n)
      t.fail(what + " has more entries than its count " + std::to_string(n) + " (expected ')' but found " +
             t.describe_next() + ")");
    const std::size_t at = t.pos();
    const std::int64_t v = t.label([&] { return "entry " + std::to_string(i) + " of " + what; });
    check(v, i, at);
    out.push_back(v);
    ++i;
  }
}

std::vector<Eigen::Vector3d> read_points(FoamText& t) {
  const std::string what = "the point list";
  const std::int64_t n = list_count(t, what);
  std::vector<Eigen::Vector3d> points;
  const char open = t.peek();
  const std::size_t list_at = t.pos();
  if (open == '{') {  // uniform: all points equal (degenerate, but well-formed)
    t.expect('{', "");
    // All points equal is never a valid mesh; the limit keeps a few bytes from costing gigabytes.
    if (n > kMaxUniformPoints)
      t.fail_at(list_at, "uniform point list of " + std::to_string(n) + " points (more than " +
                             std::to_string(kMaxUniformPoints) + ") is not a mesh");
    Eigen::Vector3d v;
    if (t.binary()) {
      const char* p = t.raw(3 * t.scalar_bytes(), what);
      for (int d = 0; d < 3; ++d) v[d] = t.raw_scalar(p + d * t.scalar_bytes());
      t.expect_raw_end('}', what);
    } else {
      t.expect('(', "to open the uniform point");
      for (int d = 0; d < 3; ++d) v[d] = t.scalar("coordinate " + std::to_string(d) + " of the uniform point");
      t.expect(')', "to close the uniform point");
      t.expect('}', "to close the uniform point list");
    }
    points.assign(static_cast<std::size_t>(n), v);
    return points;
  }
  if (open != '(') {
    if (t.binary() && n == 0) return points;
    t.fail("expected '(' to open the point list but found " + t.describe_next());
  }
  t.expect('(', "");
  if (t.binary() && n >= 0) {
    const std::size_t at = t.pos();
    const char* p = t.raw(static_cast<std::size_t>(n) * 3 * t.scalar_bytes(), what);
    points.resize(static_cast<std::size_t>(n));
    for (std::int64_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) {
        const double v = t.raw_scalar(p + (static_cast<std::size_t>(i) * 3 + d) * t.scalar_bytes());
        if (!std::isfinite(v))
          t.fail_at(at + (static_cast<std::size_t>(i) * 3 + d) * t.scalar_bytes(),
                    "point " + std::to_string(i) + " has a coordinate that is not a finite number");
        points[static_cast<std::size_t>(i)][d] = v;
      }
    t.expect_raw_end(')', what);
    return points;
  }
  if (n > 0) points.reserve(std::min(static_cast<std::size_t>(n), t.remaining() / 7));  // "(0 0 0)" 
  std::int64_t i = 0;
  while (true) {
    const char c = t.peek();
    if (c == ')') {
      if (n >= 0 && i < n)
        t.fail("the point list ends after " + std::to_string(i) + " points but its count says " + std::to_string(n) +
               ": the list is truncated or its count is wrong");
      t.expect(')', "");
      return points;
    }
    if (c == '\0')
      t.fail_at(t.pos(), "the file ends inside the point list after " + std::to_string(i) + " points: it is truncated");
    if (n >= 0 && i == n)
      t.fail("the point list has more entries than its count " + std::to_string(n) + " (expected ')' but found " +
             t.describe_next() + ")");
    if (t.peek() != '(') t.fail("expected '(' to open point " + std::to_string(i) + " but found " + t.describe_next());
    t.expect('(', "");
    Eigen::Vector3d v;
    for (int d = 0; d < 3; ++d)
      v[d] = t.scalar([&] { return std::string("the ") + "xyz"[d] + " coordinate of point " + std::to_string(i); });
    if (t.peek() != ')')
      t.fail("expected ')' to close point " + std::to_string(i) + " (a point has exactly 3 coordinates) but found " +
             t.describe_next());
    t.expect(')', "");
    points.push_back(v);
    ++i;
  }
}

void read_faces(FoamText& t, std::int64_t n_points, PolyMeshData& mesh) {
  mesh.face_offsets.assign(1, 0);
  mesh.face_points.clear();
  const auto point_check = [&](const std::string& face_name) {
    return [&t, n_points, face_name](std::int64_t v, std::int64_t, std::size_t at) {
      if (v < 0 || v >= n_points)
        t.fail_at(at, face_name + " refers to point " + std::to_string(v) + " but the point list has " +
                          std::to_string(n_points) + " points (labels 0.." + std::to_string(n_points - 1) + ")");
    };
  };
  const auto check_size = [&](std::int64_t f, std::int64_t size, std::size_t at) {
    if (size < 3)
      t.fail_at(at, "face " + std::to_string(f) + " has " + std::to_string(size) + " points; a face needs at least 3");
  };

  if (t.header("class") == "faceCompactList") {
    std::vector<std::int64_t> offsets;
    const std::size_t offsets_at = t.pos();
    // Offsets are checked against their predecessor as they come, so differences cannot overflow.
    read_label_list(t, offsets, "the face offsets", 1, [&t, &offsets](std::int64_t v, std::int64_t i, std::size_t at) {
      const std::int64_t previous = offsets.empty() ? 0 : offsets.back();
      if (v < previous || (i == 0 && v != 0))
        t.fail_at(at, "face offset " + std::to_string(i) + " is " + std::to_string(v) +
                          (i == 0 ? "; the face offsets of a faceCompactList must start with 0"
                                  : "; it is smaller than the one before (" + std::to_string(previous) +
                                        "): offsets must not decrease"));
    });
    const std::size_t labels_at = t.pos();
    read_label_list(t, mesh.face_points, "the face point labels", 1, point_check("a face"));
    if (offsets.empty() || offsets.front() != 0)
      t.fail_at(offsets_at, "the face offsets of a faceCompactList must start with 0");
    for (std::size_t f = 1; f < offsets.size(); ++f) check_size(std::int64_t(f) - 1, offsets[f] - offsets[f - 1], offsets_at);
    if (offsets.back() != static_cast<std::int64_t>(mesh.face_points.size()))
      t.fail_at(labels_at, "the face offsets end at " + std::to_string(offsets.back()) + " but there are " +
                               std::to_string(mesh.face_points.size()) + " face point labels");
    mesh.face_offsets = std::move(offsets);
    return;
  }

  const std::string what = "the face list";
  const std::int64_t n = list_count(t, what);
  if (t.peek() != '(') {
    if (t.binary() && n == 0) return;
    t.fail("expected '(' to open the face list but found " + t.describe_next());
  }
  t.expect('(', "");
  if (n > 0) {
    const auto reserve = std::min(static_cast<std::size_t>(n), t.remaining() / 8);  // "3(0 1 2)" 
    mesh.face_offsets.reserve(reserve + 1);
    mesh.face_points.reserve(4 * reserve);
  }
  std::int64_t f = 0;
  while (true) {
    const char c = t.peek();
    if (c == ')') {
      if (n >= 0 && f < n)
        t.fail("the face list ends after " + std::to_string(f) + " faces but its count says " + std::to_string(n) +
               ": the list is truncated or its count is wrong");
      t.expect(')', "");
      return;
    }
    if (c == '\0')
      t.fail_at(t.pos(), "the file ends inside the face list after " + std::to_string(f) + " faces: it is truncated");
    if (n >= 0 && f == n)
      t.fail("the face list has more entries than its count " + std::to_string(n) + " (expected ')' but found " +
             t.describe_next() + ")");
    const std::size_t at = t.pos();
    const std::string name = "face " + std::to_string(f);
    const std::int64_t size = read_label_list(t, mesh.face_points, name, 64, point_check(name));
    check_size(f, size, at);
    mesh.face_offsets.push_back(static_cast<std::int64_t>(mesh.face_points.size()));
    ++f;
  }
}

std::vector<PolyPatch> read_boundary(FoamText& t, std::int64_t n_internal, std::int64_t n_faces) {
  std::vector<PolyPatch> patches;
  std::int64_t n = -1;
  if (t.peek() != '(') n = list_count(t, "the patch list");
  t.expect('(', "to open the patch list");
  std::vector<std::size_t> where;
  while (t.peek() != ')') {
    if (t.at_end()) t.fail_at(t.pos(), "the file ends inside the patch list: it is truncated");
    const std::size_t at = t.pos();
    PolyPatch patch;
    patch.name = t.word("a patch name");
    t.expect('{', "to open the dictionary of patch '" + patch.name + "'");
    const auto entries = t.dictionary("the dictionary of patch '" + patch.name + "'");
    const auto get = [&](const char* key) -> std::string {
      const auto it = entries.find(key);
      if (it == entries.end()) t.fail_at(at, "patch '" + patch.name + "' has no '" + key + "' entry");
      return it->second;
    };
    const auto get_label = [&](const char* key) {
      const std::string s = get(key);
      std::int64_t v = -1;
      const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
      if (ec != std::errc() || ptr != s.data() + s.size() || v < 0)
        t.fail_at(at, "patch '" + patch.name + "' has '" + key + " " + s + ";', expected a non-negative integer");
      return v;
    };
    patch.type = get("type");
    patch.n_faces = get_label("nFaces");
    patch.start_face = get_label("startFace");
    if (const auto it = entries.find("neighbourPatch"); it != entries.end()) patch.neighbour_patch = it->second;
    patch.cyclic = patch.type.rfind("cyclic", 0) == 0;
    patches.push_back(std::move(patch));
    where.push_back(at);
  }
  const std::size_t end_at = t.pos();
  t.expect(')', "");
  if (n >= 0 && n != static_cast<std::int64_t>(patches.size()))
    t.fail_at(end_at, "the patch list has " + std::to_string(patches.size()) + " patches but its count says " +
                          std::to_string(n));
  std::int64_t expected = n_internal;
  for (std::size_t i = 0; i < patches.size(); ++i) {
    const auto& p = patches[i];
    // Both are >= 0; bounding them by the face count keeps expected + n_faces from overflowing.
    if (p.n_faces > n_faces || p.start_face > n_faces)
      t.fail_at(where[i], "patch '" + p.name + "' has nFaces " + std::to_string(p.n_faces) + " and startFace " +
                              std::to_string(p.start_face) + " but the mesh has only " + std::to_string(n_faces) +
                              " faces");
    if (p.start_face != expected)
      t.fail_at(where[i], "patch '" + p.name + "' starts at face " + std::to_string(p.start_face) +
                              " but the faces before it end at " + std::to_string(expected) +
                              " (patches cover the boundary faces in order, after the " + std::to_string(n_internal) +
                              " internal faces)");
    expected += p.n_faces;
  }
  if (expected != n_faces)
    t.fail_at(end_at, "the patches end at face " + std::to_string(expected) + " but the mesh has " +
                          std::to_string(n_faces) + " faces (" + std::to_string(n_internal) +
                          " internal); boundary, faces and neighbour do not belong together");
  return patches;
}

/// A cell has at least 4 faces and a face at most 2 cells, so a mesh of n_faces faces has
/// fewer than n_faces cells: a larger label is corrupt (and would overflow label + 1).
std::string cell_label_too_large(const char* list, std::int64_t face, std::int64_t label, std::int64_t n_faces) {
  return std::string(list) + " of face " + std::to_string(face) + " is cell " + std::to_string(label) +
         ", but a mesh of " + std::to_string(n_faces) + " faces has fewer than " + std::to_string(n_faces) +
         " cells (labels 0.." + std::to_string(n_faces - 1) + " at most)";
}

/// nCells from a header note such as "nPoints:3751  nCells:3000  nFaces:9700 ...", or -1.
std::int64_t noted_cell_count(const std::string& note) {
  const std::size_t at = note.find("nCells:");
  if (at == std::string::npos) return -1;
  std::int64_t v = -1;
  const char* first = note.data() + at + 7;
  while (first < note.data() + note.size() && *first == ' ') ++first;
  const auto [ptr, ec] = std::from_chars(first, note.data() + note.size(), v);
  return ec == std::errc() ? v : -1;
}

}  // namespace

std::filesystem::path polymesh_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    io_error("polyMesh folder " + dir.string() +
             " does not exist or is not a folder; give an OpenFOAM case folder (with constant/polyMesh) or its "
             "constant/polyMesh folder");
  if (fs::is_directory(dir / "constant" / "polyMesh", ec)) return dir / "constant" / "polyMesh";
  if (!fs::exists(dir / "faces", ec) && !fs::exists(dir / "faces.gz", ec) && fs::is_directory(dir / "polyMesh", ec))
    return dir / "polyMesh";  // the constant folder was given
  return dir;
}

std::vector<std::int64_t> read_label_list_file(const std::filesystem::path& dir, const std::string& name) {
  FoamText t(load(polymesh_folder(dir), name));
  std::vector<std::int64_t> labels;
  read_label_list(t, labels, "the label list " + name, kMaxCount, [](std::int64_t, std::int64_t, std::size_t) {});
  t.expect_end("the label list " + name);
  return labels;
}

PolyMeshData read_polymesh(const std::filesystem::path& dir) {
  const fs::path mesh_dir = polymesh_folder(dir);

  PolyMeshData mesh;
  mesh.source = mesh_dir.string();

  {
    FoamText t(load(mesh_dir, "points"));
    mesh.points = read_points(t);
    t.expect_end("the point list");
    if (mesh.points.size() < 4)
      t.fail_at(0, "the mesh has " + std::to_string(mesh.points.size()) + " points; a cell needs at least 4");
  }
  const auto n_points = static_cast<std::int64_t>(mesh.points.size());
  {
    FoamText t(load(mesh_dir, "faces"));
    read_faces(t, n_points, mesh);
    t.expect_end("the face list");
    if (mesh.face_offsets.size() < 5)
      t.fail_at(0, "the mesh has " + std::to_string(mesh.face_offsets.size() - 1) + " faces; a cell needs at least 4");
  }
  const auto n_faces = static_cast<std::int64_t>(mesh.face_offsets.size()) - 1;
  std::int64_t noted_cells = -1;
  std::string noted_in;
  {
    FoamText t(load(mesh_dir, "owner"));
    const std::size_t at = t.pos();
    const auto nonnegative = [&t, n_faces](std::int64_t v, std::int64_t i, std::size_t pos) {
      if (v < 0) t.fail_at(pos, "owner of face " + std::to_string(i) + " is " + std::to_string(v) + "; cell labels are >= 0");
      if (v >= n_faces) t.fail_at(pos, cell_label_too_large("owner", i, v, n_faces));
    };
    mesh.owner.reserve(static_cast<std::size_t>(n_faces));
    read_label_list(t, mesh.owner, "the owner list", n_faces, nonnegative);
    t.expect_end("the owner list");
    if (mesh.face_count() != n_faces)
      t.fail_at(at, "the owner list has " + std::to_string(mesh.face_count()) + " entries but the face list has " +
                        std::to_string(n_faces) + " faces; every face needs exactly one owner cell");
    noted_cells = noted_cell_count(t.header("note"));
    noted_in = t.file_name();
  }
  {
    FoamText t(load(mesh_dir, "neighbour"));
    const std::size_t at = t.pos();
    const auto& owner = mesh.owner;
    const auto valid = [&t, &owner, n_faces](std::int64_t v, std::int64_t i, std::size_t pos) {
      if (v < 0)
        t.fail_at(pos, "neighbour of face " + std::to_string(i) + " is " + std::to_string(v) +
                           "; cell labels are >= 0 (boundary faces have no neighbour entry)");
      if (v >= n_faces) t.fail_at(pos, cell_label_too_large("neighbour", i, v, n_faces));
      if (i < n_faces && v == owner[static_cast<std::size_t>(i)])
        t.fail_at(pos, "face " + std::to_string(i) + " has cell " + std::to_string(v) + " as both owner and neighbour");
    };
    read_label_list(t, mesh.neighbour, "the neighbour list", n_faces, valid);
    t.expect_end("the neighbour list");
    if (mesh.neighbour.size() > mesh.owner.size())
      t.fail_at(at, "the neighbour list has " + std::to_string(mesh.neighbour.size()) + " entries but there are only " +
                        std::to_string(n_faces) + " faces; the internal faces (the first ones) have one neighbour each");
    if (noted_cells < 0) {
      noted_cells = noted_cell_count(t.header("note"));
      noted_in = t.file_name();
    }
  }
  std::int64_t n_cells = 0;
  for (const auto c : mesh.owner) n_cells = std::max(n_cells, c + 1);
  for (const auto c : mesh.neighbour) n_cells = std::max(n_cells, c + 1);
  if (noted_cells >= 0 && noted_cells != n_cells)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                noted_in + ": the header note says nCells:" + std::to_string(noted_cells) + " but owner and neighbour refer to " +
                    std::to_string(n_cells) + " cells (largest label + 1); the owner/neighbour files do not belong "
                    "together: " + kRegenerate);
  {
    FoamText t(load(mesh_dir, "boundary"));
    mesh.patches = read_boundary(t, static_cast<std::int64_t>(mesh.neighbour.size()), n_faces);
    t.expect_end("the patch list");
  }
  return mesh;
}

}  // namespace vfe

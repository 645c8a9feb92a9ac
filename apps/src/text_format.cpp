#include "text_format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace vfe::apps {

std::string round_trip(double v) {
  char buf[64];
  for (int p = 6; p <= 17; ++p) {
    std::snprintf(buf, sizeof buf, "%.*g", p, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string json_number(double v) { return std::isfinite(v) ? round_trip(v) : "null"; }

std::string csv_number(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return round_trip(v);
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

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

std::string printf_number(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string table_number(const char* format, double v) {
  return std::isnan(v) ? std::string("-") : printf_number(format, v);
}

void print_columns(std::ostream& out, const std::vector<std::vector<std::string>>& rows, std::size_t left_columns) {
  if (rows.empty()) return;
  std::vector<std::size_t> w(rows[0].size(), 0);
  for (const auto& r : rows)
    for (std::size_t c = 0; c < r.size() && c < w.size(); ++c) w[c] = std::max(w[c], r[c].size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    std::string line;
    for (std::size_t c = 0; c < rows[i].size() && c < w.size(); ++c) {
      const std::string pad(w[c] - rows[i][c].size(), ' ');
      if (c) line += "  ";
      line += c < left_columns ? rows[i][c] + pad : pad + rows[i][c];
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out << line << '\n';
    if (i == 0) {
      std::size_t total = 2 * (w.size() - 1);
      for (auto x : w) total += x;
      out << std::string(total, '-') << '\n';
    }
  }
}

void check_written(const std::ostream& out, const std::filesystem::path& file) {
  if (!out)
    throw std::runtime_error(file.string() + ": cannot write the file; check that the output folder "
                                             "is writable and the disk is not full");
}

void write_text_file(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  out.flush();
  check_written(out, file);
}

}  // namespace vfe::apps

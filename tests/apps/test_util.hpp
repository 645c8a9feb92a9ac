// Helpers of the apps tests: a temporary folder and file writers.
#pragma once

#include <zlib.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace vfe::apps::test {

/// A fresh folder under the system's temporary folder, removed with its contents at the end.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "vfe_apps_test_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("cannot create a temporary folder");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

inline void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

inline void write_gzip(const std::filesystem::path& file, const std::string& text) {
  gzFile f = gzopen(file.string().c_str(), "wb");
  if (!f) throw std::runtime_error("cannot write " + file.string());
  if (!text.empty() && gzwrite(f, text.data(), static_cast<unsigned>(text.size())) != static_cast<int>(text.size())) {
    gzclose(f);
    throw std::runtime_error("gzwrite failed on " + file.string());
  }
  gzclose(f);
}

inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// One CSV line's fields; quoted fields (notes may hold commas) are kept whole.
inline std::vector<std::string> split_csv_line(const std::string& s) {
  std::vector<std::string> v;
  std::string cell;
  bool quoted = false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (quoted) {
      if (c == '"' && i + 1 < s.size() && s[i + 1] == '"') {
        cell += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cell += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      v.push_back(cell);
      cell.clear();
    } else {
      cell += c;
    }
  }
  v.push_back(cell);
  return v;
}

/// The rows of a CSV file with a header line, each as a map from column name to text.
inline std::vector<std::map<std::string, std::string>> read_csv(const std::filesystem::path& file) {
  std::istringstream in(read_text(file));
  std::string line;
  std::vector<std::string> head;
  std::vector<std::map<std::string, std::string>> rows;
  if (std::getline(in, line)) head = split_csv_line(line);
  while (std::getline(in, line)) {
    const auto v = split_csv_line(line);
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < head.size() && i < v.size(); ++i) row[head[i]] = v[i];
    rows.push_back(row);
  }
  return rows;
}

/// The internalField of an OpenFOAM volVectorField as vfe writes it (nonuniform
/// List<vector>): 3 values per cell. Throws std::runtime_error when it is not one.
inline std::vector<double> read_foam_vectors(const std::filesystem::path& file) {
  const std::string text = read_text(file);
  const std::string kind = "nonuniform List<vector>";
  const auto list = text.find(kind);
  if (list == std::string::npos) throw std::runtime_error(file.string() + ": no nonuniform List<vector>");
  std::istringstream vs(text.substr(list + kind.size()));
  std::size_t count = 0;
  std::string tok;
  vs >> count >> tok;
  if (tok != "(") throw std::runtime_error(file.string() + ": no '(' after the count");
  std::vector<double> values;
  for (std::size_t c = 0; c < count; ++c) {
    char open = 0, close = 0;
    double u[3];
    vs >> open >> u[0] >> u[1] >> u[2] >> close;
    if (!vs || open != '(' || close != ')') throw std::runtime_error(file.string() + ": vector " + std::to_string(c) + " is not (x y z)");
    values.insert(values.end(), u, u + 3);
  }
  return values;
}

}  // namespace vfe::apps::test

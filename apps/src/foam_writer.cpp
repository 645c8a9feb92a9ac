#include "foam_writer.hpp"

#include "text_format.hpp"

#include <zlib.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;

/// Whole file through zlib (which reads plain files as they are); empty on failure.
std::string read_maybe_gz(const fs::path& file) {
  gzFile f = gzopen(file.string().c_str(), "rb");
  if (!f) return {};
  std::string text;
  char buf[1 << 14];
  int n = 0;
  while ((n = gzread(f, buf, sizeof buf)) > 0) text.append(buf, static_cast<std::size_t>(n));
  gzclose(f);
  return n < 0 ? std::string() : text;
}

/// Tokens of an OpenFOAM dictionary: words (quotes removed) and the punctuation { } ( ) ;.
std::vector<std::string> tokenize(const std::string& s) {
  std::vector<std::string> out;
  std::size_t i = 0;
  const std::size_t n = s.size();
  while (i < n) {
    const char c = s[i];
    if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (c == '/' && i + 1 < n && s[i + 1] == '/') {
      while (i < n && s[i] != '\n') ++i;
    } else if (c == '/' && i + 1 < n && s[i + 1] == '*') {
      const auto e = s.find("*/", i + 2);
      i = e == std::string::npos ? n : e + 2;
    } else if (c == '"') {
      const auto e = s.find('"', i + 1);
      out.push_back(s.substr(i + 1, (e == std::string::npos ? n : e) - i - 1));
      i = e == std::string::npos ? n : e + 1;
    } else if (c == '{' || c == '}' || c == '(' || c == ')' || c == ';') {
      out.emplace_back(1, c);
      ++i;
    } else {
      const std::size_t b = i;
      while (i < n && !std::isspace(static_cast<unsigned char>(s[i])) && std::string("{}();\"").find(s[i]) == std::string::npos)
        ++i;
      out.push_back(s.substr(b, i - b));
    }
  }
  return out;
}

}  // namespace

std::vector<FoamPatch> read_constraint_patches(const fs::path& folder) {
  static const std::set<std::string> constraint = {"empty",     "wedge",     "symmetryPlane", "symmetry",
                                                   "cyclic",    "cyclicAMI", "cyclicACMI",    "cyclicSlip"};
  std::string text = read_maybe_gz(folder / "boundary");
  if (text.empty()) text = read_maybe_gz(folder / "boundary.gz");
  const std::vector<std::string> t = tokenize(text);
  std::vector<FoamPatch> out;
  std::size_t i = 0;
  // Skip the FoamFile header dictionary.
  if (i + 1 < t.size() && t[i] == "FoamFile" && t[i + 1] == "{") {
    int depth = 0;
    for (++i; i < t.size(); ++i) {
      if (t[i] == "{") ++depth;
      if (t[i] == "}" && --depth == 0) {
        ++i;
        break;
      }
    }
  }
  // Optional count, then ( name { ... type T; ... } ... ).
  while (i < t.size() && t[i] != "(") ++i;
  if (i >= t.size()) return {};
  for (++i; i + 1 < t.size() && t[i] != ")";) {
    FoamPatch p{t[i], ""};
    if (t[i + 1] != "{") return {};
    int depth = 0;
    for (i += 1; i < t.size(); ++i) {
      if (t[i] == "{") ++depth;
      else if (t[i] == "}") {
        if (--depth == 0) {
          ++i;
          break;
        }
      } else if (depth == 1 && t[i] == "type" && i + 1 < t.size() && p.type.empty()) {
        p.type = t[i + 1];
      }
    }
    if (constraint.count(p.type)) out.push_back(p);
  }
  return out;
}

namespace {

/// One ASCII vol<Type>Field: components 1 (volScalarField) or 3 (volVectorField, "(x y z)").
void write_foam_field(const fs::path& file, const std::string& object, const std::string& location,
                      std::span<const double> values, int components, const std::string& dimensions,
                      const std::vector<FoamPatch>& patches, const std::string& note) {
  const bool vector = components == 3;
  std::error_code ec;
  if (file.has_parent_path()) fs::create_directories(file.parent_path(), ec);
  std::ostringstream o;
  o << "/*--------------------------------*- C++ -*----------------------------------*\\\n"
    << "  vfe: void fraction of CFD cells from DEM particles\n"
    << "\\*---------------------------------------------------------------------------*/\n"
    << "FoamFile\n{\n"
    << "    version     2.0;\n"
    << "    format      ascii;\n"
    << "    class       " << (vector ? "volVectorField" : "volScalarField") << ";\n"
    << "    location    \"" << location << "\";\n"
    << "    object      " << object << ";\n";
  if (!note.empty()) {
    std::string n = note;
    for (char& c : n)
      if (c == '"' || c == '\n') c = ' ';
    o << "    note        \"" << n << "\";\n";
  }
  o << "}\n"
    << "// * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * //\n\n"
    << "dimensions      " << dimensions << ";\n\n"
    << "internalField   nonuniform List<" << (vector ? "vector" : "scalar") << ">\n"
    << values.size() / static_cast<std::size_t>(components) << "\n(\n";
  auto number = [](double v) { return std::isfinite(v) ? round_trip(v) : std::string("0"); };
  for (std::size_t i = 0; i + components <= values.size(); i += static_cast<std::size_t>(components))
    if (vector)
      o << '(' << number(values[i]) << ' ' << number(values[i + 1]) << ' ' << number(values[i + 2]) << ")\n";
    else
      o << number(values[i]) << '\n';
  o << ")\n;\n\n"
    << "boundaryField\n{\n"
    << "    \".*\"\n    {\n        type            zeroGradient;\n    }\n";
  for (const FoamPatch& p : patches)
    o << "    " << p.name << "\n    {\n        type            " << p.type << ";\n    }\n";
  o << "}\n\n"
    << "// ************************************************************************* //\n";
  std::ofstream out(file, std::ios::binary);
  if (!out)
    throw std::runtime_error(file.string() + ": cannot write the OpenFOAM field file; check the output folder");
  out << o.str();
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": writing the OpenFOAM field file failed (disk full?)");
}

}  // namespace

void write_foam_scalar_field(const fs::path& file, const std::string& object, const std::string& location,
                             std::span<const double> values, const std::vector<FoamPatch>& patches,
                             const std::string& note) {
  write_foam_field(file, object, location, values, 1, "[0 0 0 0 0 0 0]", patches, note);
}

void write_foam_vector_field(const fs::path& file, const std::string& object, const std::string& location,
                             std::span<const double> values, const std::string& dimensions,
                             const std::vector<FoamPatch>& patches, const std::string& note) {
  if (values.size() % 3 != 0)
    throw std::runtime_error(file.string() + ": a vector field needs 3 values per cell (got " +
                             std::to_string(values.size()) + ")");
  write_foam_field(file, object, location, values, 3, dimensions, patches, note);
}

}  // namespace vfe::apps

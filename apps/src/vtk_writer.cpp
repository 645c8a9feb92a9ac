#include "vtk_writer.hpp"

#include "text_format.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <type_traits>
#include <unordered_map>
#include <vector>
#include <stdexcept>

namespace vfe::apps {

namespace {

std::string base64(const unsigned char* data, std::size_t n) {
  static constexpr char table[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < n; i += 3) {
    const std::uint32_t v = (std::uint32_t{data[i]} << 16) | (std::uint32_t{data[i + 1]} << 8) | data[i + 2];
    out += table[(v >> 18) & 63];
    out += table[(v >> 12) & 63];
    out += table[(v >> 6) & 63];
    out += table[v & 63];
  }
  if (i < n) {
    std::uint32_t v = std::uint32_t{data[i]} << 16;
    if (i + 1 < n) v |= std::uint32_t{data[i + 1]} << 8;
    out += table[(v >> 18) & 63];
    out += table[(v >> 12) & 63];
    out += (i + 1 < n) ? table[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}


template <class T>
constexpr const char* vtk_type() {
  if constexpr (std::is_same_v<T, double>)
    return "Float64";
  else if constexpr (std::is_same_v<T, std::int64_t>)
    return "Int64";
  else
    return "UInt8";
}

/// One DataArray element: values inline as ASCII or as one base64 block (UInt64 byte count,
/// then the raw values).
template <class T>
void data_array(std::ostream& o, const std::string& name, std::span<const T> values, int components,
                VtkEncoding encoding, const char* indent = "        ") {
  o << indent << "<DataArray type=\"" << vtk_type<T>() << "\" Name=\"" << name << "\"";
  if (components > 1) o << " NumberOfComponents=\"" << components << "\"";
  o << " format=\"" << (encoding == VtkEncoding::ascii ? "ascii" : "binary") << "\">\n";
  if (encoding == VtkEncoding::ascii) {
    const std::size_t per_line = components > 1 ? static_cast<std::size_t>(components) : 6;
    for (std::size_t i = 0; i < values.size(); ++i) {
      o << (i % per_line == 0 ? std::string(indent) + "  " : std::string(" "));
      if constexpr (std::is_same_v<T, double>)
        o << round_trip(values[i]);
      else
        o << static_cast<long long>(values[i]);
      if (i % per_line == per_line - 1) o << '\n';
    }
    if (values.size() % per_line != 0) o << '\n';
  } else {
    const std::uint64_t bytes = values.size() * sizeof(T);
    std::vector<unsigned char> buf(sizeof bytes + bytes);
    std::memcpy(buf.data(), &bytes, sizeof bytes);
    if (bytes) std::memcpy(buf.data() + sizeof bytes, values.data(), bytes);
    o << indent << "  " << base64(buf.data(), buf.size()) << '\n';
  }
  o << indent << "</DataArray>\n";
}

/// The XML declaration and the VTKFile element of a file of the given type.
void open_vtk_file(std::ostream& o, const char* type) {
  const bool little = std::endian::native == std::endian::little;
  o << "<?xml version=\"1.0\"?>\n";
  o << "<VTKFile type=\"" << type << "\" version=\"1.0\" byte_order=\"" << (little ? "LittleEndian" : "BigEndian")
    << "\" header_type=\"UInt64\">\n";
}

/// s with the five XML special characters escaped, for an attribute value.
std::string xml_attribute(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace

void write_vti(const std::filesystem::path& file, const vfe::CartesianGridSpec& g,
               const std::vector<CellArray>& arrays, VtkEncoding encoding) {
  const std::int64_t n = g.cells[0] * g.cells[1] * g.cells[2];
  for (const auto& a : arrays)
    if (static_cast<std::int64_t>(a.values.size()) != n * a.components)
      throw std::runtime_error("write_vti: array '" + a.name + "' has " + std::to_string(a.values.size()) +
                               " values, the grid has " + std::to_string(n) + " cells of " +
                               std::to_string(a.components) + " component(s)");
  std::ostringstream o;
  const std::string extent =
      "0 " + std::to_string(g.cells[0]) + " 0 " + std::to_string(g.cells[1]) + " 0 " + std::to_string(g.cells[2]);
  open_vtk_file(o, "ImageData");
  o << "  <ImageData WholeExtent=\"" << extent << "\" Origin=\"" << round_trip(g.origin[0]) << ' '
    << round_trip(g.origin[1]) << ' ' << round_trip(g.origin[2]) << "\" Spacing=\"" << round_trip(g.spacing[0])
    << ' ' << round_trip(g.spacing[1]) << ' ' << round_trip(g.spacing[2]) << "\">\n";
  o << "    <Piece Extent=\"" << extent << "\">\n";
  o << "      <PointData>\n      </PointData>\n";
  o << "      <CellData" << (arrays.empty() ? "" : " Scalars=\"" + arrays.front().name + "\"") << ">\n";
  for (const auto& a : arrays) data_array<double>(o, a.name, a.values, a.components, encoding);
  o << "      </CellData>\n    </Piece>\n  </ImageData>\n</VTKFile>\n";
  write_text_file(file, o.str());
}

void write_vtu(const std::filesystem::path& file, const vfe::Engine::PolyTopology& t,
               std::span<const double> cell_centres, const std::vector<CellArray>& arrays, VtkEncoding encoding) {
  auto bad = [&](const std::string& what) {
    return std::runtime_error("write_vtu: " + file.filename().string() + ": " + what);
  };
  if (t.points.size() % 3 != 0) throw bad("the point coordinates are not a multiple of 3");
  const auto npoints = static_cast<std::int64_t>(t.points.size() / 3);
  if (t.face_offsets.empty() || t.cell_face_offsets.empty()) throw bad("empty face or cell offsets");
  const auto nfaces = static_cast<std::int64_t>(t.face_offsets.size()) - 1;
  const auto ncells = static_cast<std::int64_t>(t.cell_face_offsets.size()) - 1;
  if (static_cast<std::int64_t>(cell_centres.size()) != 3 * ncells)
    throw bad("cell_centres has " + std::to_string(cell_centres.size()) + " values for " + std::to_string(ncells) +
              " cells");
  if (t.face_offsets.front() != 0 || t.face_offsets.back() != static_cast<std::int64_t>(t.face_points.size()))
    throw bad("face_offsets do not span face_points");
  if (t.cell_face_offsets.front() != 0 ||
      t.cell_face_offsets.back() != static_cast<std::int64_t>(t.cell_faces.size()))
    throw bad("cell_face_offsets do not span cell_faces");
  for (std::int64_t f = 0; f < nfaces; ++f)
    if (t.face_offsets[f + 1] - t.face_offsets[f] < 3) throw bad("face " + std::to_string(f) + " has < 3 points");
  for (std::int64_t p : t.face_points)
    if (p < 0 || p >= npoints) throw bad("a face refers to point " + std::to_string(p) + " of " +
                                         std::to_string(npoints));
  for (std::int64_t c = 0; c < ncells; ++c)
    if (t.cell_face_offsets[c + 1] < t.cell_face_offsets[c]) throw bad("cell_face_offsets decrease");
  for (std::int64_t f : t.cell_faces)
    if (f < 0 || f >= nfaces) throw bad("a cell refers to face " + std::to_string(f) + " of " + std::to_string(nfaces));
  for (const auto& a : arrays)
    if (static_cast<std::int64_t>(a.values.size()) != ncells * a.components)
      throw std::runtime_error("write_vtu: array '" + a.name + "' has " + std::to_string(a.values.size()) +
                               " values, the mesh has " + std::to_string(ncells) + " cells of " +
                               std::to_string(a.components) + " component(s)");

  // Each face's area vector (Newell) and mean point, to turn it outwards for each cell.
  std::vector<std::array<double, 6>> face_geo(static_cast<std::size_t>(nfaces));
  for (std::int64_t f = 0; f < nfaces; ++f) {
    std::array<double, 6> g{};
    const std::int64_t b = t.face_offsets[f], e = t.face_offsets[f + 1];
    for (std::int64_t k = b; k < e; ++k) {
      const double* p = &t.points[3 * t.face_points[k]];
      const double* q = &t.points[3 * t.face_points[k + 1 < e ? k + 1 : b]];
      g[0] += 0.5 * (p[1] * q[2] - p[2] * q[1]);
      g[1] += 0.5 * (p[2] * q[0] - p[0] * q[2]);
      g[2] += 0.5 * (p[0] * q[1] - p[1] * q[0]);
      for (int d = 0; d < 3; ++d) g[3 + d] += p[d];
    }
    for (int d = 0; d < 3; ++d) g[3 + d] /= static_cast<double>(e - b);
    face_geo[static_cast<std::size_t>(f)] = g;
  }

  std::vector<std::int64_t> connectivity, offsets, faces, faceoffsets;
  offsets.reserve(static_cast<std::size_t>(ncells));
  faceoffsets.reserve(static_cast<std::size_t>(ncells));
  std::unordered_map<std::int64_t, char> seen;
  for (std::int64_t c = 0; c < ncells; ++c) {
    seen.clear();
    const double* cc = &cell_centres[3 * c];
    faces.push_back(t.cell_face_offsets[c + 1] - t.cell_face_offsets[c]);
    for (std::int64_t k = t.cell_face_offsets[c]; k < t.cell_face_offsets[c + 1]; ++k) {
      const std::int64_t f = t.cell_faces[k];
      const auto& g = face_geo[static_cast<std::size_t>(f)];
      const double out = g[0] * (g[3] - cc[0]) + g[1] * (g[4] - cc[1]) + g[2] * (g[5] - cc[2]);
      const std::int64_t b = t.face_offsets[f], e = t.face_offsets[f + 1];
      faces.push_back(e - b);
      if (out >= 0)
        for (std::int64_t i = b; i < e; ++i) faces.push_back(t.face_points[i]);
      else
        for (std::int64_t i = e; i-- > b;) faces.push_back(t.face_points[i]);
      for (std::int64_t i = b; i < e; ++i)
        if (seen.emplace(t.face_points[i], 0).second) connectivity.push_back(t.face_points[i]);
    }
    offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    faceoffsets.push_back(static_cast<std::int64_t>(faces.size()));
  }
  const std::vector<std::uint8_t> types(static_cast<std::size_t>(ncells), 42);  // VTK_POLYHEDRON

  std::ostringstream o;
  open_vtk_file(o, "UnstructuredGrid");
  o << "  <UnstructuredGrid>\n";
  o << "    <Piece NumberOfPoints=\"" << npoints << "\" NumberOfCells=\"" << ncells << "\">\n";
  o << "      <PointData>\n      </PointData>\n";
  o << "      <CellData" << (arrays.empty() ? "" : " Scalars=\"" + arrays.front().name + "\"") << ">\n";
  for (const auto& a : arrays) data_array<double>(o, a.name, a.values, a.components, encoding);
  o << "      </CellData>\n";
  o << "      <Points>\n";
  data_array<double>(o, "Points", t.points, 3, encoding);
  o << "      </Points>\n";
  o << "      <Cells>\n";
  data_array<std::int64_t>(o, "connectivity", connectivity, 1, encoding);
  data_array<std::int64_t>(o, "offsets", offsets, 1, encoding);
  data_array<std::uint8_t>(o, "types", types, 1, encoding);
  data_array<std::int64_t>(o, "faces", faces, 1, encoding);
  data_array<std::int64_t>(o, "faceoffsets", faceoffsets, 1, encoding);
  o << "      </Cells>\n";
  o << "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  write_text_file(file, o.str());
}

void write_vtp(const std::filesystem::path& file, std::span<const double> centres, std::span<const double> radii,
               std::span<const double> velocities, std::span<const std::int64_t> ids, VtkEncoding encoding) {
  const std::size_t n = radii.size();
  auto check = [&](const char* name, std::size_t size, std::size_t per) {
    if (size != per * n)
      throw std::runtime_error("write_vtp: " + file.filename().string() + ": " + name + " has " + std::to_string(size) +
                               " values for " + std::to_string(n) + " particles of " + std::to_string(per) +
                               " component(s)");
  };
  check("centres", centres.size(), 3);
  if (!velocities.empty()) check("velocities", velocities.size(), 3);
  if (!ids.empty()) check("ids", ids.size(), 1);
  std::vector<std::int64_t> connectivity(n), offsets(n);
  for (std::size_t i = 0; i < n; ++i) {
    connectivity[i] = static_cast<std::int64_t>(i);
    offsets[i] = static_cast<std::int64_t>(i + 1);
  }
  std::ostringstream o;
  open_vtk_file(o, "PolyData");
  o << "  <PolyData>\n";
  o << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfVerts=\"" << n
    << "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  o << "      <PointData Scalars=\"radius\"" << (velocities.empty() ? "" : " Vectors=\"velocity\"") << ">\n";
  data_array<double>(o, "radius", radii, 1, encoding);
  if (!velocities.empty()) data_array<double>(o, "velocity", velocities, 3, encoding);
  if (!ids.empty()) data_array<std::int64_t>(o, "id", ids, 1, encoding);
  o << "      </PointData>\n";
  o << "      <Points>\n";
  data_array<double>(o, "Points", centres, 3, encoding);
  o << "      </Points>\n";
  o << "      <Verts>\n";
  data_array<std::int64_t>(o, "connectivity", connectivity, 1, encoding);
  data_array<std::int64_t>(o, "offsets", offsets, 1, encoding);
  o << "      </Verts>\n";
  o << "    </Piece>\n  </PolyData>\n</VTKFile>\n";
  write_text_file(file, o.str());
}

void write_pvd(const std::filesystem::path& file, const std::vector<PvdEntry>& entries) {
  std::ostringstream o;
  open_vtk_file(o, "Collection");
  o << "  <Collection>\n";
  for (const PvdEntry& e : entries)
    o << "    <DataSet timestep=\"" << round_trip(e.time) << "\" part=\"0\" file=\""
      << xml_attribute(e.file.generic_string()) << "\"/>\n";
  o << "  </Collection>\n</VTKFile>\n";
  write_text_file(file, o.str());
}

}  // namespace vfe::apps

#include "vtk_writer.hpp"

#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
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

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

void write_vti(const std::filesystem::path& file, const vfe::CartesianGridSpec& g,
               const std::vector<CellArray>& arrays, VtkEncoding encoding) {
  const std::int64_t n = g.cells[0] * g.cells[1] * g.cells[2];
  for (const auto& a : arrays)
    if (static_cast<std::int64_t>(a.values.size()) != n)
      throw std::runtime_error("write_vti: array '" + a.name + "' has " + std::to_string(a.values.size()) +
                               " values, the grid has " + std::to_string(n) + " cells");
  const bool little = std::endian::native == std::endian::little;
  std::ostringstream o;
  const std::string extent =
      "0 " + std::to_string(g.cells[0]) + " 0 " + std::to_string(g.cells[1]) + " 0 " + std::to_string(g.cells[2]);
  o << "<?xml version=\"1.0\"?>\n";
  o << "<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"" << (little ? "LittleEndian" : "BigEndian")
    << "\" header_type=\"UInt64\">\n";
  o << "  <ImageData WholeExtent=\"" << extent << "\" Origin=\"" << num(g.origin[0]) << ' ' << num(g.origin[1])
    << ' ' << num(g.origin[2]) << "\" Spacing=\"" << num(g.spacing[0]) << ' ' << num(g.spacing[1]) << ' '
    << num(g.spacing[2]) << "\">\n";
  o << "    <Piece Extent=\"" << extent << "\">\n";
  o << "      <PointData>\n      </PointData>\n";
  o << "      <CellData" << (arrays.empty() ? "" : " Scalars=\"" + arrays.front().name + "\"") << ">\n";
  for (const auto& a : arrays) {
    o << "        <DataArray type=\"Float64\" Name=\"" << a.name << "\" NumberOfComponents=\"1\" format=\""
      << (encoding == VtkEncoding::ascii ? "ascii" : "binary") << "\">\n";
    if (encoding == VtkEncoding::ascii) {
      for (std::size_t i = 0; i < a.values.size(); ++i)
        o << (i % 6 == 0 ? "          " : " ") << num(a.values[i]) << (i % 6 == 5 ? "\n" : "");
      if (a.values.size() % 6 != 0) o << '\n';
    } else {
      // Uncompressed inline binary: one base64 stream of the UInt64 byte count and the data.
      const std::uint64_t bytes = a.values.size() * sizeof(double);
      std::vector<unsigned char> buf(sizeof bytes + bytes);
      std::memcpy(buf.data(), &bytes, sizeof bytes);
      if (bytes) std::memcpy(buf.data() + sizeof bytes, a.values.data(), bytes);
      o << "          " << base64(buf.data(), buf.size()) << '\n';
    }
    o << "        </DataArray>\n";
  }
  o << "      </CellData>\n    </Piece>\n  </ImageData>\n</VTKFile>\n";
  std::ofstream out(file, std::ios::binary);
  if (!out) throw std::runtime_error(file.string() + ": cannot write the VTK file; check the output folder");
  out << o.str();
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": writing the VTK file failed (disk full?)");
}

}  // namespace vfe::apps

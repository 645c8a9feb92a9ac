#include "shape_spec.hpp"

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace vfe {

namespace {

[[noreturn]] void bad_spec(std::string_view spec, const std::string& why) {
  throw Error(VFE_ERROR_INVALID_ARGUMENT,
              "shape '" + std::string(spec) + "': " + why +
                  "; expected sphere | ellipsoid A B C | superquadric A B C E1 E2 | clump x y z r; ... | mesh FILE");
}

std::vector<double> numbers(std::string_view spec, std::istringstream& in, std::size_t count) {
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end != tok.c_str() + tok.size() || !std::isfinite(x)) bad_spec(spec, "'" + tok + "' is not a number");
    v.push_back(x);
  }
  if (v.size() != count)
    bad_spec(spec, "needs " + std::to_string(count) + " numbers, got " + std::to_string(v.size()));
  return v;
}

/// Merges vertices by exact position so triangles of an STL (which repeats positions)
/// share indices.
struct VertexIndex {
  std::map<std::array<double, 3>, int> ids;
  kernels::TriangleMesh mesh;
  int id(const Eigen::Vector3d& p) {
    auto [it, inserted] = ids.try_emplace({p[0], p[1], p[2]}, static_cast<int>(mesh.vertices.size()));
    if (inserted) mesh.vertices.push_back(p);
    return it->second;
  }
};

kernels::TriangleMesh read_stl(const std::string& path, const std::string& bytes) {
  VertexIndex vi;
  // Binary STL: 80-byte header, uint32 count, 50 bytes per triangle. A file whose size
  // matches that is binary even if its header starts with "solid".
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (bytes.size() == 84 + std::size_t(n) * 50) {
      for (std::uint32_t t = 0; t < n; ++t) {
        const char* rec = bytes.data() + 84 + std::size_t(t) * 50;
        Eigen::Vector3i tri;
        for (int k = 0; k < 3; ++k) {
          float xyz[3];
          std::memcpy(xyz, rec + 12 + 12 * k, 12);
          tri[k] = vi.id(Eigen::Vector3d(xyz[0], xyz[1], xyz[2]));
        }
        vi.mesh.triangles.push_back(tri);
      }
      return vi.mesh;
    }
  }
  std::istringstream in(bytes);
  std::string line, word;
  int lineno = 0;
  std::vector<int> facet;
  while (std::getline(in, line)) {
    ++lineno;
    std::istringstream ls(line);
    if (!(ls >> word)) continue;
    if (word == "vertex") {
      double x, y, z;
      if (!(ls >> x >> y >> z))
        throw Error(VFE_ERROR_INVALID_ARGUMENT,
                    path + ":" + std::to_string(lineno) + ": 'vertex' needs three numbers; fix the STL file");
      facet.push_back(vi.id(Eigen::Vector3d(x, y, z)));
    } else if (word == "endfacet") {
      if (facet.size() != 3)
        throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ":" + std::to_string(lineno) + ": a facet has " +
                                                    std::to_string(facet.size()) + " vertices, not 3");
      vi.mesh.triangles.emplace_back(facet[0], facet[1], facet[2]);
      facet.clear();
    }
  }
  if (vi.mesh.triangles.empty())
    throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ": no triangles found (neither binary nor ASCII STL)");
  return vi.mesh;
}

kernels::TriangleMesh read_obj(const std::string& path, const std::string& bytes) {
  kernels::TriangleMesh mesh;
  std::istringstream in(bytes);
  std::string line, word;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    std::istringstream ls(line);
    if (!(ls >> word)) continue;
    if (word == "v") {
      double x, y, z;
      if (!(ls >> x >> y >> z))
        throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ":" + std::to_string(lineno) + ": 'v' needs three numbers");
      mesh.vertices.emplace_back(x, y, z);
    } else if (word == "f") {
      std::vector<int> ids;
      std::string ref;
      while (ls >> ref) {
        // "i", "i/t", "i//n" or "i/t/n"; negative indices count from the end.
        const int i = std::atoi(ref.c_str());
        if (i == 0)
          throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ":" + std::to_string(lineno) + ": bad face index '" + ref + "'");
        ids.push_back(i > 0 ? i - 1 : static_cast<int>(mesh.vertices.size()) + i);
      }
      if (ids.size() < 3)
        throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ":" + std::to_string(lineno) + ": a face needs 3 vertices");
      for (std::size_t k = 1; k + 1 < ids.size(); ++k) mesh.triangles.emplace_back(ids[0], ids[k], ids[k + 1]);
    }
  }
  return mesh;
}

}  // namespace

kernels::TriangleMesh read_triangle_mesh(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(VFE_ERROR_IO, "cannot open mesh file '" + path + "'; check the path (relative to the working folder)");
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::string lower = path;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower.size() >= 4 && lower.compare(lower.size() - 4, 4, ".obj") == 0) return read_obj(path, bytes);
  if (lower.size() >= 4 && lower.compare(lower.size() - 4, 4, ".stl") == 0) return read_stl(path, bytes);
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "mesh file '" + path + "': unknown format; use .stl (ASCII or binary) or .obj");
}

kernels::Shape parse_shape_spec(std::string_view spec) {
  std::istringstream in{std::string(spec)};
  std::string kind;
  in >> kind;
  try {
    if (kind == "sphere") {
      numbers(spec, in, 0);
      return kernels::Shape::sphere();
    }
    if (kind == "ellipsoid") {
      const auto v = numbers(spec, in, 3);
      return kernels::Shape::ellipsoid(v[0], v[1], v[2]);
    }
    if (kind == "superquadric") {
      const auto v = numbers(spec, in, 5);
      return kernels::Shape::superquadric(v[0], v[1], v[2], v[3], v[4]);
    }
    if (kind == "clump") {
      std::string rest;
      std::getline(in, rest);
      std::vector<Eigen::Vector4d> spheres;
      std::istringstream parts(rest);
      std::string part;
      while (std::getline(parts, part, ';')) {
        if (part.find_first_not_of(" \t") == std::string::npos) continue;
        std::istringstream ps(part);
        const auto v = numbers(spec, ps, 4);
        spheres.emplace_back(v[0], v[1], v[2], v[3]);
      }
      return kernels::Shape::clump(std::move(spheres));
    }
    if (kind == "mesh") {
      std::string path;
      std::getline(in >> std::ws, path);
      while (!path.empty() && std::isspace(static_cast<unsigned char>(path.back()))) path.pop_back();
      if (path.empty()) bad_spec(spec, "mesh needs a file name");
      return kernels::Shape::mesh(read_triangle_mesh(path));
    }
  } catch (const std::invalid_argument& e) {
    bad_spec(spec, e.what());
  }
  bad_spec(spec, kind.empty() ? "empty spec" : "unknown shape '" + kind + "'");
}

}  // namespace vfe

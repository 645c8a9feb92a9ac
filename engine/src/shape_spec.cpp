#include "shape_spec.hpp"

#include "parse_number.hpp"

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
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
    const auto x = parse_finite_double(tok);
    if (!x) bad_spec(spec, "'" + tok + "' is not a finite number");
    v.push_back(*x);
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

[[noreturn]] void bad_mesh_line(const std::string& path, int lineno, const std::string& why) {
  throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ":" + std::to_string(lineno) + ": " + why);
}

void check_triangle_count(const std::string& path, std::uint64_t n) {
  if (n > kernels::kMaxMeshTriangles)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                path + ": " + std::to_string(n) + " triangles, more than the limit of " +
                    std::to_string(kernels::kMaxMeshTriangles) +
                    " a mesh shape may have; simplify the surface (e.g. quadric decimation in MeshLab or Blender) "
                    "to fewer triangles, which a particle's template does not need");
}

/// Three strict numbers x y z from the rest of `ls` (more only when extra_numbers_allowed).
Eigen::Vector3d three_numbers(std::istringstream& ls, const std::string& path, int lineno, const char* keyword,
                              bool extra_numbers_allowed) {
  Eigen::Vector3d v;
  std::string tok;
  int got = 0;
  while (ls >> tok) {
    const auto x = parse_finite_double(tok);
    if (!x)
      bad_mesh_line(path, lineno, std::string("'") + keyword + "' has '" + tok + "', which is not a finite number");
    if (got < 3) v[got] = *x;
    ++got;
  }
  if (got < 3 || (got > 3 && !extra_numbers_allowed))
    bad_mesh_line(path, lineno, std::string("'") + keyword + "' needs exactly three numbers x y z, got " +
                                    std::to_string(got));
  return v;
}

kernels::TriangleMesh read_stl(const std::string& path, const std::string& bytes) {
  VertexIndex vi;
  // Binary STL: 80-byte header, uint32 count, 50 bytes per triangle. A file whose size
  // matches that is binary even if its header starts with "solid".
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (bytes.size() == 84 + std::size_t(n) * 50) {
      check_triangle_count(path, n);
      vi.mesh.triangles.reserve(n);
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
      if (facet.size() >= 3) bad_mesh_line(path, lineno, "a facet has more than 3 vertices; fix the STL file");
      facet.push_back(vi.id(three_numbers(ls, path, lineno, "vertex", false)));
    } else if (word == "endfacet") {
      if (facet.size() != 3)
        bad_mesh_line(path, lineno, "a facet has " + std::to_string(facet.size()) + " vertices, not 3");
      check_triangle_count(path, vi.mesh.triangles.size() + 1);
      vi.mesh.triangles.emplace_back(facet[0], facet[1], facet[2]);
      facet.clear();
    }
  }
  if (!facet.empty())
    bad_mesh_line(path, lineno, "the file ends inside a facet (" + std::to_string(facet.size()) +
                                    " vertices, no 'endfacet'): it is truncated");
  if (vi.mesh.triangles.empty())
    throw Error(VFE_ERROR_INVALID_ARGUMENT, path + ": no triangles found (neither binary nor ASCII STL)");
  return vi.mesh;
}

/// The vertex of an OBJ face reference "i", "i/t", "i//n" or "i/t/n" (1-based, or negative
/// counting back from the last vertex read), as a 0-based index in [0, n_vertices).
int obj_vertex(const std::string& ref, std::size_t n_vertices, const std::string& path, int lineno) {
  const std::string_view all(ref);
  const std::string_view index = all.substr(0, all.find('/'));
  // The texture and normal parts are not used, but must be integers (or empty) too.
  for (std::size_t at = index.size(); at < all.size();) {
    const std::size_t next = std::min(all.find('/', at + 1), all.size());
    const std::string_view part = all.substr(at + 1, next - at - 1);
    if (!part.empty() && !parse_int64(part))
      bad_mesh_line(path, lineno, "face reference '" + ref + "' has '" + std::string(part) + "', not an integer");
    at = next;
  }
  const auto i = parse_int64(index);
  const auto n = static_cast<std::int64_t>(n_vertices);
  if (!i || *i == 0 || *i > n || *i < -n)
    bad_mesh_line(path, lineno, "face reference '" + ref + "' is not a vertex: give an integer in 1.." + std::to_string(n) +
                                    " (or -" + std::to_string(n) + "..-1, counting back) for the " + std::to_string(n) +
                                    " vertices read so far");
  return static_cast<int>(*i > 0 ? *i - 1 : n + *i);
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
      // x y z, optionally followed by w or by a colour r g b (written by some tools).
      if (mesh.vertices.size() >= 3 * kernels::kMaxMeshTriangles)
        bad_mesh_line(path, lineno, "more than " + std::to_string(3 * kernels::kMaxMeshTriangles) +
                                        " vertices; simplify the surface to at most " +
                                        std::to_string(kernels::kMaxMeshTriangles) + " triangles");
      mesh.vertices.push_back(three_numbers(ls, path, lineno, "v", true));
    } else if (word == "f") {
      std::vector<int> ids;
      std::string ref;
      while (ls >> ref) ids.push_back(obj_vertex(ref, mesh.vertices.size(), path, lineno));
      if (ids.size() < 3) bad_mesh_line(path, lineno, "a face needs 3 vertices");
      check_triangle_count(path, mesh.triangles.size() + ids.size() - 2);
      for (std::size_t k = 1; k + 1 < ids.size(); ++k) mesh.triangles.emplace_back(ids[0], ids[k], ids[k + 1]);
    }
  }
  return mesh;
}

}  // namespace

kernels::TriangleMesh read_triangle_mesh(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error(VFE_ERROR_IO, "mesh file '" + path + "' is a folder; give the path of an .stl or .obj file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(VFE_ERROR_IO, "cannot open mesh file '" + path + "'; check the path (relative to the working folder)");
  std::string bytes;
  try {  // a read error surfaces as an exception from the stream buffer (e.g. EISDIR)
    bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  } catch (const std::exception& e) {
    throw Error(VFE_ERROR_IO, "reading mesh file '" + path + "' failed (" + e.what() + "); check that it is a readable file");
  }
  if (f.bad()) throw Error(VFE_ERROR_IO, "reading mesh file '" + path + "' failed; check that it is a readable file");
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

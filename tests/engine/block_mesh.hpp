// A block of hexahedra as a polyMesh, for tests that need a box mesh of a chosen size.
#pragma once

#include "polymesh/polymesh.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace vfe::test {

/// A block of hexahedra between the given node coordinates, numbered as blockMesh does
/// (points and cells x fastest; internal faces by owner, then by neighbour; one "walls"
/// patch with the boundary faces).
inline PolyMeshData block_mesh(const std::array<std::vector<double>, 3>& x) {
  PolyMeshData d;
  const std::int64_t nx = std::int64_t(x[0].size()) - 1, ny = std::int64_t(x[1].size()) - 1,
                     nz = std::int64_t(x[2].size()) - 1;
  const auto pid = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  const auto cid = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return i + nx * (j + ny * k); };
  for (std::int64_t k = 0; k <= nz; ++k)
    for (std::int64_t j = 0; j <= ny; ++j)
      for (std::int64_t i = 0; i <= nx; ++i)
        d.points.emplace_back(x[0][std::size_t(i)], x[1][std::size_t(j)], x[2][std::size_t(k)]);
  // The face of cell (i, j, k) on the + side of axis a, normal along +a.
  const auto plus_face = [&](int a, std::int64_t i, std::int64_t j, std::int64_t k) -> std::array<std::int64_t, 4> {
    if (a == 0) return {pid(i + 1, j, k), pid(i + 1, j + 1, k), pid(i + 1, j + 1, k + 1), pid(i + 1, j, k + 1)};
    if (a == 1) return {pid(i, j + 1, k), pid(i, j + 1, k + 1), pid(i + 1, j + 1, k + 1), pid(i + 1, j + 1, k)};
    return {pid(i, j, k + 1), pid(i + 1, j, k + 1), pid(i + 1, j + 1, k + 1), pid(i, j + 1, k + 1)};
  };
  const auto add = [&](std::array<std::int64_t, 4> f, bool reverse, std::int64_t own) {
    if (reverse) std::reverse(f.begin(), f.end());
    d.face_points.insert(d.face_points.end(), f.begin(), f.end());
    d.face_offsets.push_back(std::int64_t(d.face_points.size()));
    d.owner.push_back(own);
  };
  for (std::int64_t k = 0; k < nz; ++k)
    for (std::int64_t j = 0; j < ny; ++j)
      for (std::int64_t i = 0; i < nx; ++i) {
        if (i + 1 < nx) { add(plus_face(0, i, j, k), false, cid(i, j, k)); d.neighbour.push_back(cid(i + 1, j, k)); }
        if (j + 1 < ny) { add(plus_face(1, i, j, k), false, cid(i, j, k)); d.neighbour.push_back(cid(i, j + 1, k)); }
        if (k + 1 < nz) { add(plus_face(2, i, j, k), false, cid(i, j, k)); d.neighbour.push_back(cid(i, j, k + 1)); }
      }
  const auto internal = std::int64_t(d.owner.size());
  for (std::int64_t k = 0; k < nz; ++k)
    for (std::int64_t j = 0; j < ny; ++j)
      for (std::int64_t i = 0; i < nx; ++i) {
        if (i == 0) add(plus_face(0, i - 1, j, k), true, cid(i, j, k));
        if (i == nx - 1) add(plus_face(0, i, j, k), false, cid(i, j, k));
        if (j == 0) add(plus_face(1, i, j - 1, k), true, cid(i, j, k));
        if (j == ny - 1) add(plus_face(1, i, j, k), false, cid(i, j, k));
        if (k == 0) add(plus_face(2, i, j, k - 1), true, cid(i, j, k));
        if (k == nz - 1) add(plus_face(2, i, j, k), false, cid(i, j, k));
      }
  d.patches.push_back({"walls", "wall", internal, std::int64_t(d.owner.size()) - internal, "", false});
  return d;
}

/// n + 1 evenly spaced coordinates from lo to hi.
inline std::vector<double> nodes(int n, double lo, double hi) {
  std::vector<double> x(std::size_t(n) + 1);
  for (int i = 0; i <= n; ++i) x[std::size_t(i)] = lo + (hi - lo) * i / n;
  return x;
}

}  // namespace vfe::test

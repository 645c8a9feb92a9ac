// Test cells: hexahedra given by their faces, and warped grids of them that tile a box.
#pragma once

#include <vfe/kernels/polytope.hpp>
#include <vfe/kernels/shape.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace vfe::test {

/// A polyhedral cell in sphere_polyhedron_overlap's face layout.
struct FacedCell {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::int32_t> offsets{0, 4, 8, 12, 16, 20, 24};
  std::vector<std::int32_t> faces{0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
};

/// Hexahedron with corners[i + 2 j + 4 k] (i, j, k in {0, 1} along its three edge
/// directions); faces counter-clockwise seen from outside.
inline FacedCell hex_cell(const std::array<Eigen::Vector3d, 8>& corners) {
  FacedCell c;
  c.vertices.assign(corners.begin(), corners.end());
  return c;
}

inline FacedCell box_cell(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  std::array<Eigen::Vector3d, 8> c;
  for (int k = 0; k < 8; ++k) c[k] = {k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]};
  return hex_cell(c);
}

/// m^3 hexahedra tiling the box [lo, hi]: the interior grid nodes moved at random by up
/// to `jitter` of the spacing (so faces are warped), the boundary nodes kept on the box.
inline std::vector<FacedCell> warped_grid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int m, double jitter,
                                          unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  const Eigen::Vector3d h = (hi - lo) / m;
  std::vector<Eigen::Vector3d> nodes;
  for (int k = 0; k <= m; ++k)
    for (int j = 0; j <= m; ++j)
      for (int i = 0; i <= m; ++i) {
        Eigen::Vector3d p = lo + Eigen::Vector3d(i * h[0], j * h[1], k * h[2]);
        const int idx[3] = {i, j, k};
        for (int d = 0; d < 3; ++d)
          if (idx[d] > 0 && idx[d] < m) p[d] += u(rng) * h[d];
        nodes.push_back(p);
      }
  const auto node = [&](int i, int j, int k) { return nodes[std::size_t(i + (m + 1) * (j + (m + 1) * k))]; };
  std::vector<FacedCell> cells;
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        std::array<Eigen::Vector3d, 8> c;
        for (int q = 0; q < 8; ++q) c[q] = node(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
        cells.push_back(hex_cell(c));
      }
  return cells;
}

/// The signed tetrahedra of a faced cell (the kernels' TetrahedraView layout).
inline std::vector<Eigen::Vector3d> cell_tetrahedra(const FacedCell& c) {
  std::vector<Eigen::Vector3d> tets;
  kernels::for_each_face_tetrahedron(c.vertices, c.offsets, c.faces,
                            [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& p,
                                const Eigen::Vector3d& q) { tets.insert(tets.end(), {a, b, p, q}); });
  return tets;
}

/// Volume of the corner simplex {x >= 0, x + y + z <= 1} inside [lo, hi]: inclusion-
/// exclusion over the corners c of the box clamped to the orthant, each orthant
/// {x >= c} cutting (1 - sum c)^3 / 6 from the simplex.
inline double simplex_box_volume(Eigen::Vector3d lo, Eigen::Vector3d hi) {
  lo = lo.cwiseMax(0.0);
  hi = hi.cwiseMax(0.0);
  if ((hi - lo).minCoeff() <= 0) return 0;
  double v = 0;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d c(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]);
    const int highs = (k & 1) + ((k >> 1) & 1) + ((k >> 2) & 1);
    v += (highs % 2 ? -1.0 : 1.0) * std::pow(std::max(0.0, 1.0 - c.sum()), 3) / 6.0;
  }
  return v;
}

/// The box [lo, hi] as a closed triangle mesh (two triangles per face).
inline kernels::TriangleMesh box_mesh(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  kernels::TriangleMesh m;
  for (int k = 0; k < 8; ++k) m.vertices.emplace_back(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]);
  const FacedCell c = box_cell(lo, hi);
  for (std::size_t f = 0; f + 1 < c.offsets.size(); ++f) {
    const int* q = &c.faces[std::size_t(c.offsets[f])];
    m.triangles.emplace_back(q[0], q[1], q[2]);
    m.triangles.emplace_back(q[0], q[2], q[3]);
  }
  return m;
}

/// The corner tetrahedron (0, x, y, z).
inline kernels::TriangleMesh tetrahedron_mesh() {
  kernels::TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

}  // namespace vfe::test

// Rectilinear grid: per-axis node coordinates, O(log n) point location, x-fastest order.
#pragma once

#include "polymesh/polymesh_reader.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace vfe {

/// A grid of boxes between strictly increasing node coordinates per axis. Cell (i, j, k)
/// spans [x_i, x_{i+1}) x [y_j, y_{j+1}) x [z_k, z_{k+1}) and has index i + nx*(j + ny*k)
/// (x fastest, as CartesianGrid and blockMesh). All functions are const and thread-safe.
class RectilinearGrid {
 public:
  /// nodes[d] holds the node coordinates along axis d: at least 2, finite, strictly
  /// increasing. Throws Error (VFE_ERROR_INVALID_ARGUMENT) naming the axis and the node.
  explicit RectilinearGrid(std::array<std::vector<double>, 3> nodes);

  std::int64_t cell_count() const { return n_[0] * n_[1] * n_[2]; }
  /// Cells per axis.
  const std::array<std::int64_t, 3>& cells() const { return n_; }
  const std::vector<double>& nodes(int d) const { return nodes_[static_cast<std::size_t>(d)]; }
  Eigen::Vector3d lower() const { return {nodes_[0].front(), nodes_[1].front(), nodes_[2].front()}; }
  Eigen::Vector3d upper() const { return {nodes_[0].back(), nodes_[1].back(), nodes_[2].back()}; }

  std::int64_t index(std::int64_t i, std::int64_t j, std::int64_t k) const { return i + n_[0] * (j + n_[1] * k); }
  /// (i, j, k) of cell c.
  std::array<std::int64_t, 3> ijk(std::int64_t c) const { return {c % n_[0], (c / n_[0]) % n_[1], c / (n_[0] * n_[1])}; }

  /// Cell coordinate of x along axis d: i with x_i <= x < x_{i+1}; -1 below the first node,
  /// n (the cell count of the axis) at or above the last node. A point on an interior node
  /// goes to the cell above it. (Equal buckets over the axis narrow the binary search to
  /// the nodes in x's bucket, usually none or one.)
  std::int64_t axis_index(int d, double x) const;
  /// Cell holding p, or -1 outside [lower, upper) (the upper faces are outside), as
  /// CartesianGrid::locate.
  std::int64_t locate(const Eigen::Vector3d& p) const;
  /// The cell nearest to p (p's cell when inside): axis indices clamped to the grid.
  std::int64_t nearest(const Eigen::Vector3d& p) const;

  double cell_volume(std::int64_t c) const;
  Eigen::Vector3d cell_centre(std::int64_t c) const;
  /// Volumes of all cells in cell order.
  std::vector<double> cell_volumes() const;

  /// The same cells as an OpenFOAM-style polyMesh (hexahedra in this grid's cell order,
  /// internal faces in upper-triangular order, boundary patches xmin, xmax, ymin, ymax,
  /// zmin, zmax), so every polyMesh method and locator serves it.
  PolyMeshData polymesh_data() const;

 private:
  /// x's bucket along axis d (x at or above the first node): monotone in x, so a node in a
  /// lower bucket lies at or below x and one in a higher bucket above it.
  std::size_t bucket(int d, double x) const {
    const auto k = static_cast<std::size_t>(d);
    const double t = (x - nodes_[k].front()) * bucket_scale_[k];
    return t < double(bucket_last_[k]) ? static_cast<std::size_t>(t) : bucket_last_[k];
  }

  std::array<std::vector<double>, 3> nodes_;
  std::array<std::int64_t, 3> n_{};
  // Per axis: buckets 0..bucket_last_ of equal width (the last one open above), and for
  // each bucket b the number of nodes in buckets below b (bucket_first_[b], b up to
  // bucket_last_ + 1).
  std::array<double, 3> bucket_scale_{};
  std::array<std::size_t, 3> bucket_last_{};
  std::array<std::vector<std::int32_t>, 3> bucket_first_;
};

}  // namespace vfe

// Uniform Cartesian grid: O(1) point location, x-fastest cell order.
#pragma once

#include <vfe/engine.hpp>

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>

namespace vfe {

class CartesianGrid {
 public:
  /// Validates the spec (finite origin, spacing > 0, cells >= 1, at most 2^40 cells, a
  /// cell volume whose value and inverse are normal doubles, a finite far corner); throws Error.
  explicit CartesianGrid(const CartesianGridSpec& spec);

  std::int64_t cell_count() const { return n_[0] * n_[1] * n_[2]; }
  double cell_volume() const { return h_[0] * h_[1] * h_[2]; }
  /// The origin of the grid this one is a block of (global node 0); node(d, 0) is this
  /// grid's lower corner.
  const Eigen::Vector3d& origin() const { return o_; }
  const Eigen::Vector3d& spacing() const { return h_; }
  const std::array<std::int64_t, 3>& cells() const { return n_; }
  /// Coordinate of node i (the lower face of local cell i) along axis d. Every position of
  /// the grid is computed from the global index first + i, so that a block of a larger grid
  /// (CartesianGridSpec::first_cell) gives the larger grid's coordinates bit for bit.
  double node(int d, std::int64_t i) const { return o_[d] + double(first_[d] + i) * h_[d]; }
  /// Coordinate of the centre of local cell i along axis d.
  double centre(int d, std::int64_t i) const { return o_[d] + (double(first_[d] + i) + 0.5) * h_[d]; }
  Eigen::Vector3d lower() const { return {node(0, 0), node(1, 0), node(2, 0)}; }
  Eigen::Vector3d upper() const { return {node(0, n_[0]), node(1, n_[1]), node(2, n_[2])}; }
  /// The global index of local cell 0 along axis d (CartesianGridSpec::first_cell).
  std::int64_t first(int d) const { return first_[d]; }
  bool is_block() const { return first_[0] != 0 || first_[1] != 0 || first_[2] != 0; }

  /// Integer cell coordinate of x along axis d (floor; may be outside [0, n), and is
  /// bounded by +-2^60 so that far-away points stay representable).
  std::int64_t axis_index(int d, double x) const { return fast_floor(axis_coordinate(d, x)) - first_[d]; }

  /// floor(t) as an integer without a libm call (baseline x86-64 has no SSE4.1 round).
  static std::int64_t fast_floor(double t) {
    constexpr double kBound = 1.152921504606846976e18;  // 2^60
    t = t < -kBound ? -kBound : (t > kBound ? kBound : t);
    const auto i = static_cast<std::int64_t>(t);
    return i - (t < static_cast<double>(i));
  }
  /// Coordinate of x in cell units of the global grid along axis d (local cell i spans
  /// [first + i, first + i + 1)): the argument of axis_index's floor. Global, because a
  /// coordinate shifted by whole cells would round differently from the larger grid's.
  double axis_coordinate(int d, double x) const { return (x - o_[d]) * inv_h_[d]; }
  std::int64_t clamp_axis(int d, std::int64_t i) const { return i < 0 ? 0 : (i >= n_[d] ? n_[d] - 1 : i); }

  /// Periodic axes (bit d for axis d): what leaves one side enters the opposite one.
  void set_periodic(unsigned mask) { periodic_ = mask; }
  bool periodic(int d) const { return (periodic_ >> d) & 1u; }
  unsigned periodic_mask() const { return periodic_; }
  std::int64_t wrap_axis(int d, std::int64_t i) const { return ((i % n_[d]) + n_[d]) % n_[d]; }
  /// The mesh cell of integer coordinate i along axis d: wrapped on a periodic axis,
  /// -1 outside otherwise.
  std::int64_t cell_axis(int d, std::int64_t i) const {
    if (periodic(d)) return wrap_axis(d, i);
    return i < 0 || i >= n_[d] ? -1 : i;
  }
  std::int64_t index(std::int64_t i, std::int64_t j, std::int64_t k) const { return i + n_[0] * (j + n_[1] * k); }

  /// Cell holding p, or -1 when p is outside the grid. Points on an interior face go to
  /// the cell above it; points on the upper boundary are outside.
  std::int64_t locate(const Eigen::Vector3d& p) const {
    const std::int64_t i = cell_axis(0, axis_index(0, p[0])), j = cell_axis(1, axis_index(1, p[1])),
                       k = cell_axis(2, axis_index(2, p[2]));
    if (i < 0 || j < 0 || k < 0) return -1;
    return index(i, j, k);
  }
  /// The cell nearest to p (p itself when inside): indices clamped to the grid (wrapped
  /// on periodic axes).
  std::int64_t nearest(const Eigen::Vector3d& p) const {
    std::int64_t g[3];
    for (int d = 0; d < 3; ++d) {
      const std::int64_t i = axis_index(d, p[d]);
      g[d] = periodic(d) ? wrap_axis(d, i) : clamp_axis(d, i);
    }
    return index(g[0], g[1], g[2]);
  }
  /// Cell size as docs/design.md defines it: cube root of the cell volume.
  double cell_size() const { return std::cbrt(cell_volume()); }

 private:
  Eigen::Vector3d o_, h_, inv_h_;
  std::array<std::int64_t, 3> n_, first_;
  unsigned periodic_ = 0;
};

}  // namespace vfe

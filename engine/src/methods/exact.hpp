// exact on a Cartesian grid, the case of nearly every sphere at chi >= 1: a window of at
// most two cells per axis, whose volumes are the parts of the ball cut by the window's
// interior planes, in one closed-form call (kernels::unit_ball_octants).
#pragma once

#include "methods/driver.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <cstdint>
#include <limits>

namespace vfe::detail {

/// The volumes of the window lo..hi (cell coordinates per axis, hi - lo <= 1) of sphere p:
/// parts[i + 2j + 4k] is local cell (i, j, k)'s, 0 where the window has one cell on an axis.
inline void exact_window_parts(const CartesianGrid& grid, const Particle& p, const std::int64_t lo[3],
                               const std::int64_t hi[3], double parts[8]) {
  const double inverse_radius = 1.0 / p.radius;
  double plane[3];
  for (int d = 0; d < 3; ++d)
    plane[d] = hi[d] > lo[d] ? (grid.node(d, hi[d]) - p.centre[d]) * inverse_radius
                             : std::numeric_limits<double>::infinity();
  kernels::unit_ball_octants(plane[0], plane[1], plane[2], parts);
  const double r3 = p.radius * p.radius * p.radius;
  for (int m = 0; m < 8; ++m) parts[m] *= r3;
}

/// The cells lo..hi (per axis) of sphere p's box when they all lie in a grid without
/// periodic axes, at most two per axis; false otherwise (or for NaN).
[[gnu::always_inline]] inline bool exact_quick_window(const CartesianGrid& grid, const Particle& p, std::int64_t lo[3], std::int64_t hi[3]) {
  if (grid.periodic_mask()) return false;
  for (int d = 0; d < 3; ++d) {
    // axis_index's cells, tested in cell units first: inside the grid, floor is a
    // truncation on a grid from the origin (not a block).
    const double from = grid.axis_coordinate(d, p.centre[d] - p.radius);
    const double to = grid.axis_coordinate(d, p.centre[d] + p.radius);
    const std::int64_t first = grid.first(d);
    if (!(from >= double(first) && to < double(first + grid.cells()[d]))) return false;  // or NaN
    lo[d] = (first == 0 ? static_cast<std::int64_t>(from) : CartesianGrid::fast_floor(from)) - first;
    hi[d] = (first == 0 ? static_cast<std::int64_t>(to) : CartesianGrid::fast_floor(to)) - first;
    if (hi[d] - lo[d] > 1) return false;
  }
  return true;
}

/// The parts of sphere p over a window lo..hi of exact_quick_window to sink(cell, volume),
/// all 8, zeros included (a part not in the window is 0 and names a window cell), so that a
/// sink adding into a field needs no branch the processor would mispredict. Counts the
/// window's cells as sub-elements, as exact_particle does.
template <class Sink>
void exact_window_deposit(const CartesianGrid& grid, Scratch& s, const Particle& p, const std::int64_t lo[3],
                          const std::int64_t hi[3], Sink&& sink) {
  const std::int64_t base = grid.index(lo[0], lo[1], lo[2]);
  const std::int64_t step[3] = {hi[0] - lo[0], (hi[1] - lo[1]) * grid.cells()[0],
                                (hi[2] - lo[2]) * grid.cells()[0] * grid.cells()[1]};
  s.sub_elements += (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
  double parts[8];
  exact_window_parts(grid, p, lo, hi, parts);
  for (int m = 0; m < 8; ++m)
    sink(base + (m & 1 ? step[0] : 0) + (m & 2 ? step[1] : 0) + (m & 4 ? step[2] : 0), parts[m]);
}

/// exact's quick case, on a grid without periodic axes: a sphere whose cells all lie in the
/// grid, at most two per axis, goes to sink(cell, volume): the fast path's one deposit when
/// it lies in one cell, else exact_window_deposit's 8 parts. Counts as exact_particle does.
/// False, with nothing added or counted, for any other sphere.
template <class Sink>
bool exact_sphere_quick(const Context& ctx, Scratch& s, const Particle& p, Sink&& sink) {
  std::int64_t lo[3], hi[3];
  if (!exact_quick_window(ctx.grid, p, lo, hi)) return false;
  if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2] && ctx.opts.fast_path) {
    ++s.fast_path;
    sink(ctx.grid.index(lo[0], lo[1], lo[2]), p.volume);
    return true;
  }
  exact_window_deposit(ctx.grid, s, p, lo, hi, sink);
  return true;
}

}  // namespace vfe::detail

// Drivers of the separable spreading methods (gaussian, porous_cube, trilinear): per-axis
// weights over a window of cells, their product into the window, then the window's
// deposits through the outside policy.
#pragma once

#include "methods/driver.hpp"

#include <vfe/kernels/separable.hpp>

#include <algorithm>

namespace vfe::detail {

/// s.axis[d] holds the weights of the window's cells along axis d (sizes w.m[d]); deposits
/// volume times their product.
inline void deposit_separable(const Context& ctx, Scratch& s, const Particle& p, const Window& w) {
  s.window.assign(w.size(), 0.0);
  const int m0 = static_cast<int>(w.m[0]), m1 = static_cast<int>(w.m[1]), m2 = static_cast<int>(w.m[2]);
  kernels::separable_deposit(s.axis[0].data(), m0, s.axis[1].data(), m1, s.axis[2].data(), m2, p.volume,
                             [&s, m0, m1](int i, int j, int k, double v) {
                               s.window[static_cast<std::size_t>(i + m0 * (j + m1 * k))] = v;
                             });
  emit_window(ctx, s, p, w, p.outside);
}

/// A kernel of half-width `half` around the centre: the whole particle to one cell when
/// the kernel lies inside it (fast path), else axis_weights(u, h, nodes, m, out) per axis
/// (u: centre in cell units, h: spacing, nodes: the window's m + 1 node coordinates in cell
/// units) and their product into the window.
template <class AxisWeights>
void spread_separable(const Context& ctx, Scratch& s, const Particle& p, const Eigen::Vector3d& half,
                      AxisWeights&& axis_weights) {
  const CartesianGrid& grid = ctx.grid;
  if (const std::int64_t cell = single_cell(ctx, p.centre, half); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  const Window w = make_window(grid, p.centre, half);
  check_footprint(p.index, double(std::max({w.m[0], w.m[1], w.m[2]})), double(w.m[0]) * double(w.m[1]) * double(w.m[2]));
  for (int d = 0; d < 3; ++d) {
    window_nodes(grid, w, d, s.nodes[d]);
    s.axis[d].resize(static_cast<std::size_t>(w.m[d]));
    axis_weights(grid.axis_coordinate(d, p.centre[d]), grid.spacing()[d], s.nodes[d].data(),
                 static_cast<int>(w.m[d]), s.axis[d].data());
  }
  s.sub_elements += static_cast<std::int64_t>(w.size());
  deposit_separable(ctx, s, p, w);
}

}  // namespace vfe::detail

// porous_cube: the particle volume spread uniformly over an axis-aligned cube of side
// gamma * d_p around the centre; each cell gets the exact fraction of the cube it overlaps
// (kernels/porous_cube.hpp). The part beyond the mesh follows the outside policy.
#include "methods/separable.hpp"

#include <vfe/kernels/porous_cube.hpp>

namespace vfe::detail {

void porous_cube_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  const double half_side = ctx.opts.gamma * p.radius;
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(half_side);
  if (const std::int64_t cell = single_cell(grid, p.centre, half); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  const Window w = make_window(grid, p.centre, half);
  for (int d = 0; d < 3; ++d) {
    window_nodes(grid, w, d, s.nodes[d]);
    s.axis[d].resize(static_cast<std::size_t>(w.m[d]));
    const double u = grid.axis_coordinate(d, p.centre[d]), a = half_side / grid.spacing()[d];
    kernels::interval_axis_weights(u - a, u + a, s.nodes[d].data(), static_cast<int>(w.m[d]), s.axis[d].data());
  }
  s.sub_elements += static_cast<std::int64_t>(w.size());
  deposit_separable(ctx, s, p, w);
}

}  // namespace vfe::detail

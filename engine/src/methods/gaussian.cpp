// gaussian: the particle volume spread by a normalised Gaussian of standard deviation
// sigma * d_p around the centre, cut at 3 sigma per axis (kernels/gaussian.hpp). Each cell
// gets the kernel's integral over it; the tails beyond the mesh follow the outside policy.
#include "methods/separable.hpp"

#include <vfe/kernels/gaussian.hpp>

namespace vfe::detail {

void gaussian_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  const double sigma = ctx.opts.sigma * 2.0 * p.radius;
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(kernels::kGaussianCut * sigma);
  // The fast path holds when the whole cut kernel lies in one cell.
  if (const std::int64_t cell = single_cell(grid, p.centre, half); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  const Window w = make_window(grid, p.centre, half);
  for (int d = 0; d < 3; ++d) {
    window_nodes(grid, w, d, s.nodes[d]);
    s.axis[d].resize(static_cast<std::size_t>(w.m[d]));
    // In cell units: centre and sigma divided by the spacing.
    kernels::gaussian_axis_weights(grid.axis_coordinate(d, p.centre[d]), sigma / grid.spacing()[d],
                                   s.nodes[d].data(), static_cast<int>(w.m[d]), s.axis[d].data());
  }
  s.sub_elements += static_cast<std::int64_t>(w.size());
  deposit_separable(ctx, s, p, w);
}

}  // namespace vfe::detail

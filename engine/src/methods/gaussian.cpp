// gaussian: the particle volume spread by a normalised Gaussian of standard deviation
// sigma * d_p around the centre, cut at 3 sigma per axis (kernels/gaussian.hpp). Each cell
// gets the kernel's integral over it; the tails beyond the mesh follow the outside policy.
#include "methods/separable.hpp"

#include <vfe/kernels/gaussian.hpp>

namespace vfe::detail {

void gaussian_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const double sigma = ctx.opts.sigma * 2.0 * p.radius;
  // The fast path holds when the whole cut kernel lies in one cell.
  spread_separable(ctx, s, p, Eigen::Vector3d::Constant(kernels::kGaussianCut * sigma),
                   [sigma](double u, double h, const double* nodes, int m, double* out) {
                     kernels::gaussian_axis_weights(u, sigma / h, nodes, m, out);  // in cell units
                   });
}

}  // namespace vfe::detail

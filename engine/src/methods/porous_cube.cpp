// porous_cube: the particle volume spread uniformly over an axis-aligned cube of side
// gamma * d_p around the centre; each cell gets the exact fraction of the cube it overlaps
// (kernels/porous_cube.hpp). The part beyond the mesh follows the outside policy.
#include "methods/separable.hpp"

#include <vfe/kernels/porous_cube.hpp>

namespace vfe::detail {

void porous_cube_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const double half_side = ctx.opts.gamma * p.radius;
  spread_separable(ctx, s, p, Eigen::Vector3d::Constant(half_side),
                   [half_side](double u, double h, const double* nodes, int m, double* out) {
                     kernels::interval_axis_weights(u - half_side / h, u + half_side / h, nodes, m, out);
                   });
}

}  // namespace vfe::detail

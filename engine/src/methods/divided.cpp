// divided: CFDEMcoupling's 29 points of equal volume (kernels/divided.hpp), not rotated.
// As in CFDEM, a point found in no cell goes to the particle's own (centre) cell: the
// default outside=nearest acts as outside=centre here; centre, drop and error apply as
// for every method.
#include "methods/driver.hpp"

#include <vfe/kernels/divided.hpp>

namespace vfe::detail {

void divided_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const Outside policy = p.outside == Outside::nearest ? Outside::centre : p.outside;
  const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();  // CFDEM's points are not rotated
  deposit_points(ctx, s, p, ctx.divided, &identity, policy);
}

}  // namespace vfe::detail

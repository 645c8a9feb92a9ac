// divided: CFDEMcoupling's 29 points of equal volume (kernels/divided.hpp), not rotated.
// As in CFDEM, a point found in no cell goes to the particle's own (centre) cell: the
// default outside=nearest acts as outside=centre here; centre, drop and error apply as
// for every method.
#include "methods/driver.hpp"

#include <vfe/kernels/divided.hpp>

namespace vfe::detail {

void divided_particle(const Context& ctx, Scratch& s, const Particle& p) {
  s.count_grid(kernels::kDividedPoints);
  if (const std::int64_t cell = single_cell(ctx, p.centre, Eigen::Vector3d::Constant(p.radius)); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  s.sub_elements += kernels::kDividedPoints;
  const Outside policy = ctx.opts.outside == Outside::nearest ? Outside::centre : ctx.opts.outside;
  deposit_points(ctx, s, p, ctx.divided, Eigen::Matrix3d::Identity(), policy);
}

}  // namespace vfe::detail

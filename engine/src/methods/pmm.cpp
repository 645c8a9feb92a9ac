// pmm: the particle meshing method. The particle's template (kernels/particle_template.hpp:
// spherical, fibonacci or voxel family, sized by particle_grid) is rotated, scaled by the
// radius and moved to the centre; each sub-element's volume goes to the cell holding its
// centroid.
#include "methods/driver.hpp"

namespace vfe::detail {

void pmm_particle(const Context& ctx, Scratch& s, const Particle& p) {
  deposit_points(ctx, s, p, ctx.template_for(p, s), nullptr, p.outside);
}

Eigen::Matrix3d particle_rotation(const Options& opts, const Particle& p) {
  switch (opts.orientation) {
    case Orientation::none: break;
    case Orientation::random:
      return opts.rotation_bank ? kernels::banked_random_rotation(p.rotation_key, opts.seed)
                                : kernels::random_rotation(p.rotation_key, opts.seed);
    case Orientation::given: return kernels::rotation_from_quaternion(p.orientation);
  }
  return Eigen::Matrix3d::Identity();
}

const float* particle_rotation_rows(const Options& opts, const Particle& p, float buffer[9]) {
  if (opts.orientation == Orientation::random && opts.rotation_bank)
    return kernels::banked_random_rotation_rows(p.rotation_key, opts.seed);
  kernels::rotation_rows(particle_rotation(opts, p), buffer);
  return buffer;
}

}  // namespace vfe::detail

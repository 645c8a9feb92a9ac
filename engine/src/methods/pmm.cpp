// pmm: the particle meshing method. The particle's template (kernels/particle_template.hpp:
// spherical, fibonacci or voxel family, sized by particle_grid) is rotated, scaled by the
// radius and moved to the centre; each sub-element's volume goes to the cell holding its
// centroid.
#include "methods/driver.hpp"

namespace vfe::detail {

void pmm_particle(const Context& ctx, Scratch& s, const Particle& p) {
  deposit_points(ctx, s, p, ctx.template_for(2 * p.radius), nullptr, ctx.opts.outside);
}

Eigen::Matrix3d particle_rotation(const Options& opts, const Particle& p) {
  switch (opts.orientation) {
    case Orientation::none: break;
    case Orientation::random:
      return opts.rotation_bank ? kernels::banked_random_rotation(std::uint64_t(p.index), opts.seed)
                                : kernels::random_rotation(std::uint64_t(p.index), opts.seed);
    case Orientation::given: return kernels::rotation_from_quaternion(p.orientation);
  }
  return Eigen::Matrix3d::Identity();
}

void shape_particle(const Context& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate* tmpl,
                    const Eigen::Vector3d& centroid) {
  const Eigen::Matrix3d rotation = particle_rotation(ctx.opts, p);
  if (!tmpl) {
    const Eigen::Vector3d at = p.centre + p.radius * (rotation * centroid);
    ++s.sub_elements;
    bool flagged = false;
    if (const std::int64_t cell = ctx.grid.locate(at); cell >= 0)
      s.add(cell, p.volume);
    else
      outside(ctx, s, p, p.volume, ctx.grid.nearest(at), flagged, ctx.opts.outside);
    return;
  }
  deposit_points(ctx, s, p, *tmpl, &rotation, ctx.opts.outside);
}

}  // namespace vfe::detail

// pmm: the particle meshing method. The particle's template (kernels/particle_template.hpp:
// spherical, fibonacci or voxel family, sized by particle_grid) is rotated, scaled by the
// radius and moved to the centre; each sub-element's volume goes to the cell holding its
// centroid.
#include "methods/driver.hpp"

namespace vfe::detail {

void pmm_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const kernels::ParticleTemplate& t = ctx.template_for(2 * p.radius);
  const std::int64_t n = static_cast<std::int64_t>(t.size());
  s.count_grid(n);
  if (const std::int64_t cell = single_cell(ctx.grid, p.centre, Eigen::Vector3d::Constant(p.radius)); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  s.sub_elements += n;
  Eigen::Matrix3d rotation;
  switch (ctx.opts.orientation) {
    case Orientation::none: rotation.setIdentity(); break;
    case Orientation::random: rotation = kernels::random_rotation(std::uint64_t(p.index), ctx.opts.seed); break;
    case Orientation::given: rotation = kernels::rotation_from_quaternion(p.orientation); break;
  }
  deposit_points(ctx, s, p, t, rotation, ctx.opts.outside);
}

}  // namespace vfe::detail

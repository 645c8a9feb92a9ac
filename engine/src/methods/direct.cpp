// direct: the whole particle volume to the cell holding its centre (CFDEM `centre`); for a
// shaped particle, the cell holding its centroid.
#include "methods/driver.hpp"

namespace vfe::detail {

void direct_particle(const Context& ctx, Scratch& s, const Particle& p) {
  ++s.sub_elements;
  if (p.shaped) {
    const Eigen::Vector3d at = p.centre + p.radius * (particle_rotation(ctx.opts, p) * p.centroid);
    bool flagged = false;
    if (const std::int64_t cell = ctx.grid.locate(at); cell >= 0)
      s.add(cell, p.volume);
    else
      outside(ctx, s, p, p.volume, ctx.grid.nearest(at), flagged, p.outside);
    return;
  }
  bool flagged = false;
  if (const std::int64_t cell = ctx.grid.locate(p.centre); cell >= 0)
    s.add(cell, p.volume);
  else
    outside(ctx, s, p, p.volume, ctx.grid.nearest(p.centre), flagged, p.outside);
}

}  // namespace vfe::detail

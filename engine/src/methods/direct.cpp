// direct: the whole particle volume to the cell holding its centre (CFDEM `centre`).
#include "methods/driver.hpp"

namespace vfe::detail {

void direct_particle(const Context& ctx, Scratch& s, const Particle& p) {
  ++s.sub_elements;
  const std::int64_t cell = ctx.grid.locate(p.centre);
  bool flagged = false;
  if (cell >= 0)
    s.add(cell, p.volume);
  else
    outside(ctx, s, p, p.volume, ctx.grid.nearest(p.centre), flagged, ctx.opts.outside);
}

}  // namespace vfe::detail

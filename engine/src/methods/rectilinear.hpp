// direct, pmm and exact on a rectilinear (graded Cartesian) grid: per-axis binary search to
// locate, the closed-form sphere-box overlaps on the grid's own nodes for exact, and
// periodic axes by wrapping (points) or by node coordinates continued past the ends (exact).
#pragma once

#include "methods/driver.hpp"
#include "polymesh/rectilinear_grid.hpp"

namespace vfe::detail {

struct RectilinearContext {
  const RectilinearGrid& grid;
  const Options& opts;
};

/// One sphere or shaped particle (p.centre already wrapped into periodic axes). pmm
/// deposits template t (scaled by p.radius, rotated); with t null, direct puts everything
/// at the body's centroid (zero for spheres); exact (method=exact, spheres only) ignores t.
void rectilinear_particle(const RectilinearContext& ctx, Scratch& s, const Particle& p,
                          const kernels::ParticleTemplate* t, const Eigen::Vector3d& centroid);

}  // namespace vfe::detail

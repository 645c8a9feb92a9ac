// exact: the exact overlap volume of the sphere with every cell it reaches
// (kernels/sphere_box_overlap.hpp); what lies beyond the mesh follows the outside policy.
#include "methods/driver.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <algorithm>

namespace vfe::detail {

void exact_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  if (const std::int64_t cell = single_cell(ctx, c, Eigen::Vector3d::Constant(r)); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  std::int64_t lo[3], hi[3];
  bool empty = false;
  for (int d = 0; d < 3; ++d) {
    lo[d] = grid.axis_index(d, c[d] - r);
    hi[d] = grid.axis_index(d, c[d] + r);
    if (grid.periodic(d)) continue;  // cells beyond the side wrap (in the sink below)
    lo[d] = std::max<std::int64_t>(lo[d], 0);
    hi[d] = std::min<std::int64_t>(hi[d], grid.cells()[d] - 1);
    if (lo[d] > hi[d]) empty = true;
  }
  bool flagged = false;
  if (empty) {
    outside(ctx, s, p, p.volume, grid.nearest(c), flagged, p.outside);
    return;
  }
  check_footprint(p.index, double(std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}) + 1),
                  double(hi[0] - lo[0] + 1) * double(hi[1] - lo[1] + 1) * double(hi[2] - lo[2] + 1));
  int m[3];
  for (int d = 0; d < 3; ++d) {
    m[d] = static_cast<int>(hi[d] - lo[d] + 1);
    s.nodes[d].resize(m[d] + 1);
    for (int i = 0; i <= m[d]; ++i) s.nodes[d][i] = grid.node(d, lo[d] + i);
  }
  s.sub_elements += std::int64_t(m[0]) * m[1] * m[2];
  double inside = 0;
  kernels::sphere_patch_overlaps(c, r, s.nodes[0].data(), m[0], s.nodes[1].data(), m[1], s.nodes[2].data(), m[2],
                                 s.orthant, s.patch, [&](int i, int j, int k, double v) {
                                   s.add(grid.index(grid.cell_axis(0, lo[0] + i), grid.cell_axis(1, lo[1] + j),
                                                    grid.cell_axis(2, lo[2] + k)),
                                         v);
                                   inside += v;
                                 });
  // What the patch misses lies outside the mesh (beyond round-off).
  const double rest = p.volume - inside;
  if (rest > 1e-12 * p.volume) outside(ctx, s, p, rest, grid.nearest(c), flagged, p.outside);
}

}  // namespace vfe::detail

// exact: the exact overlap volume of the sphere with every cell it reaches
// (kernels/sphere_box_overlap.hpp); what lies beyond the mesh follows the outside policy.
#include "methods/exact.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <algorithm>

namespace vfe::detail {

namespace {

/// A window of at most two cells per axis that exact_sphere_quick does not take (a periodic
/// axis, or cells beyond the mesh): the same parts, each to its (wrapped) cell; the parts in
/// cells beyond the mesh through the outside policy, as the patch path below sends them.
/// False, with nothing added, for a wider window.
bool exact_octants(const Context& ctx, Scratch& s, const Particle& p, const std::int64_t lo[3],
                   const std::int64_t hi[3]) {
  const CartesianGrid& grid = ctx.grid;
  std::int64_t cell[3][2];
  std::int64_t mesh_cells = 1;  // the window's cells in the mesh (the patch path's count)
  for (int d = 0; d < 3; ++d) {
    if (hi[d] - lo[d] > 1) return false;
    cell[d][0] = grid.cell_axis(d, lo[d]);
    cell[d][1] = hi[d] > lo[d] ? grid.cell_axis(d, hi[d]) : -1;
    mesh_cells *= std::int64_t(cell[d][0] >= 0) + std::int64_t(cell[d][1] >= 0);
  }
  s.sub_elements += mesh_cells;
  double parts[8];
  exact_window_parts(grid, p, lo, hi, parts);
  double beyond = 0;
  for (int m = 0; m < 8; ++m) {
    if (!(parts[m] > 0.0)) continue;
    const std::int64_t gi = cell[0][m & 1], gj = cell[1][(m >> 1) & 1], gk = cell[2][(m >> 2) & 1];
    if (gi < 0 || gj < 0 || gk < 0)
      beyond += parts[m];
    else
      s.add(grid.index(gi, gj, gk), parts[m]);  // merges the cells a periodic axis of one cell repeats
  }
  bool flagged = false;
  if (beyond > 1e-12 * p.volume) outside(ctx, s, p, beyond, grid.nearest(p.centre), flagged, p.outside);
  return true;
}

}  // namespace

void exact_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  // The quick case's cells with a volume are distinct: into an empty list they need no merge.
  const bool fresh = s.deposits.empty();
  if (exact_sphere_quick(ctx, s, p, [&s, fresh](std::int64_t cell, double v) {
        if (!(v > 0.0)) return;
        if (fresh)
          s.deposits.push_back({cell, v});
        else
          s.add(cell, v);
      }))
    return;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  std::int64_t lo[3], hi[3];
  for (int d = 0; d < 3; ++d) {
    lo[d] = grid.axis_index(d, c[d] - r);
    hi[d] = grid.axis_index(d, c[d] + r);
  }
  if (const std::int64_t cell = single_cell(ctx, c, Eigen::Vector3d::Constant(r)); cell >= 0) {
    ++s.fast_path;  // a periodic grid's sphere in one cell
    s.add(cell, p.volume);
    return;
  }
  if (exact_octants(ctx, s, p, lo, hi)) return;
  bool empty = false;
  for (int d = 0; d < 3; ++d) {
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

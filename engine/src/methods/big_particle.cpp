// big_particle: CFDEMcoupling's rule; the particle volume shared equally by the cells whose
// centres lie within the particle, or all to its own cell when there is none
// (kernels/big_particle.hpp). Cell centres continue beyond the mesh, and the shares of
// those cells follow the outside policy, as does a particle whose own cell is beyond it.
#include "methods/driver.hpp"

#include <vfe/kernels/big_particle.hpp>

#include <algorithm>
#include <limits>
#include <cmath>

namespace vfe::detail {

void big_particle_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  if (const std::int64_t cell = single_cell(ctx, c, Eigen::Vector3d::Constant(p.radius)); cell >= 0) {
    ++s.fast_path;  // only this cell's centre can lie within the particle
    s.add(cell, p.volume);
    return;
  }
  // Lattice cells g whose centres o + (g + 1/2) h can lie within the particle, per axis.
  std::int64_t g0[3];
  int m[3];
  bool far = false;
  for (int d = 0; d < 3; ++d) {
    const double u = grid.axis_coordinate(d, c[d]), a = p.radius / grid.spacing()[d];
    if (!(std::abs(u) + a < 0x1p40)) far = true;
    if (far) break;
    // In local cells (axis_coordinate is global).
    g0[d] = static_cast<std::int64_t>(std::ceil(u - a - 0.5)) - grid.first(d);
    const std::int64_t g1 = static_cast<std::int64_t>(std::floor(u + a - 0.5)) - grid.first(d);
    // Cell centres tested: bounded before anything is sized by them.
    check_footprint(p.index, double(g1 - g0[d] + 1), std::pow(double(g1 - g0[d] + 1), 3.0));
    m[d] = static_cast<int>(std::max<std::int64_t>(g1 - g0[d] + 1, 0));
    s.nodes[d].resize(static_cast<std::size_t>(m[d]));
    for (int i = 0; i < m[d]; ++i)
      s.nodes[d][i] = grid.centre(d, g0[d] + i);
  }
  bool flagged = false;
  if (far) {  // absurdly far from the mesh: one point
    outside(ctx, s, p, p.volume, grid.nearest(c), flagged, p.outside);
    return;
  }
  s.sub_elements += std::int64_t(m[0]) * m[1] * m[2];
  // Window over the lattice range, clamped to the virtual layer around the mesh.
  Window w;
  for (int d = 0; d < 3; ++d) {
    const std::int64_t n = grid.cells()[d];
    // On a periodic axis the lattice range is kept whole (emit_window wraps it).
    const std::int64_t lo = grid.periodic(d) ? std::numeric_limits<std::int64_t>::min() : -1;
    const std::int64_t hi = grid.periodic(d) ? std::numeric_limits<std::int64_t>::max() : n;
    w.lo[d] = std::clamp<std::int64_t>(g0[d], lo, hi);
    w.m[d] = m[d] > 0 ? std::clamp<std::int64_t>(g0[d] + m[d] - 1, lo, hi) - w.lo[d] + 1 : 1;
  }
  s.window.assign(w.size(), 0.0);
  const std::int64_t count = kernels::big_particle_deposit(
      c, p.radius, p.volume, s.nodes[0].data(), m[0], s.nodes[1].data(), m[1], s.nodes[2].data(), m[2],
      [&](int i, int j, int k, double v) {
        std::int64_t l[3];
        const int ijk[3] = {i, j, k};
        for (int d = 0; d < 3; ++d)
          l[d] = (grid.periodic(d) ? g0[d] + ijk[d] : std::clamp<std::int64_t>(g0[d] + ijk[d], -1, grid.cells()[d])) -
                 w.lo[d];
        s.window[static_cast<std::size_t>(l[0] + w.m[0] * (l[1] + w.m[1] * l[2]))] += v;
      });
  if (count > 0) {
    emit_window(ctx, s, p, w, p.outside);
    return;
  }
  // No cell centre within the particle: its own cell.
  if (const std::int64_t cell = grid.locate(c); cell >= 0)
    s.add(cell, p.volume);
  else
    outside(ctx, s, p, p.volume, grid.nearest(c), flagged, p.outside);
}

}  // namespace vfe::detail

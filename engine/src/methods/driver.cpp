#include "methods/driver.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace vfe::detail {

void window_nodes(const CartesianGrid& grid, const Window& w, int d, std::vector<double>& nodes) {
  const std::int64_t n = grid.cells()[d];
  nodes.resize(static_cast<std::size_t>(w.m[d] + 1));
  for (std::int64_t i = 0; i <= w.m[d]; ++i) {
    const std::int64_t g = w.lo[d] + i, global = g + grid.first(d);
    if (grid.periodic(d)) {
      nodes[i] = double(global);
      continue;
    }
    nodes[i] = g < 0 ? -std::numeric_limits<double>::infinity()
                     : (g > n ? std::numeric_limits<double>::infinity() : double(global));
  }
}

std::int64_t single_cell(const Context& ctx, const Eigen::Vector3d& c, const Eigen::Vector3d& half) {
  if (!ctx.opts.fast_path) return -1;
  const CartesianGrid& grid = ctx.grid;
  std::int64_t idx[3];
  for (int d = 0; d < 3; ++d) {
    const std::int64_t lo = grid.axis_index(d, c[d] - half[d]);
    if (lo != grid.axis_index(d, c[d] + half[d]) || lo < 0 || lo >= grid.cells()[d]) return -1;
    idx[d] = lo;
  }
  return grid.index(idx[0], idx[1], idx[2]);
}

void outside(const Context& ctx, Scratch& s, const Particle& p, double volume, std::int64_t nearest_cell,
             bool& flagged, Outside policy) {
  apply_outside(s, p, volume, policy, ctx.grid.cell_count(), flagged, [&] { return nearest_cell; },
                [&] { return ctx.grid.nearest(p.centre); });
}

void emit_window(const Context& ctx, Scratch& s, const Particle& p, const Window& w, Outside policy) {
  const CartesianGrid& grid = ctx.grid;
  bool any_outside = false;
  std::size_t local = 0;
  for (std::int64_t k = 0; k < w.m[2]; ++k)
    for (std::int64_t j = 0; j < w.m[1]; ++j)
      for (std::int64_t i = 0; i < w.m[0]; ++i, ++local) {
        const double v = s.window[local];
        if (v == 0.0) continue;
        const std::int64_t gi = grid.cell_axis(0, w.lo[0] + i), gj = grid.cell_axis(1, w.lo[1] + j),
                           gk = grid.cell_axis(2, w.lo[2] + k);
        if (gi < 0 || gj < 0 || gk < 0)
          any_outside = true;
        else
          s.deposits.push_back({grid.index(gi, gj, gk), v});
      }
  if (!any_outside) return;
  bool flagged = false;
  local = 0;
  for (std::int64_t k = 0; k < w.m[2]; ++k)
    for (std::int64_t j = 0; j < w.m[1]; ++j)
      for (std::int64_t i = 0; i < w.m[0]; ++i, ++local) {
        const double v = s.window[local];
        std::int64_t g[3] = {w.lo[0] + i, w.lo[1] + j, w.lo[2] + k};
        bool out = false;
        for (int d = 0; d < 3; ++d) {
          out |= grid.cell_axis(d, g[d]) < 0;
          g[d] = grid.periodic(d) ? grid.wrap_axis(d, g[d]) : grid.clamp_axis(d, g[d]);
        }
        if (v == 0.0 || !out) continue;
        outside(ctx, s, p, v, grid.index(g[0], g[1], g[2]), flagged, policy);
      }
}

void deposit_points(const Context& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                    const Eigen::Matrix3d* rotation, Outside policy) {
  const CartesianGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  s.count_grid(static_cast<std::int64_t>(t.size()));
  // Map template points straight to cell units relative to the window of cells the
  // particle can reach, so locating is a truncation and a clamp per axis and deposits
  // accumulate without a search.
  const Window w = make_window(grid, c, Eigen::Vector3d::Constant(r * t.reach));
  if (w.size() == 1 && ctx.opts.fast_path) {  // every sub-element in one cell
    const std::int64_t gi = grid.cell_axis(0, w.lo[0]), gj = grid.cell_axis(1, w.lo[1]), gk = grid.cell_axis(2, w.lo[2]);
    if (gi >= 0 && gj >= 0 && gk >= 0) {
      ++s.fast_path;
      s.add(grid.index(gi, gj, gk), p.volume);
      return;
    }
  }
  s.sub_elements += static_cast<std::int64_t>(t.size());
  const Eigen::Vector3d inv_h = grid.spacing().cwiseInverse();
  const Eigen::Matrix3d R = rotation ? *rotation : particle_rotation(ctx.opts, p);
  Eigen::Vector3d base;
  for (int d = 0; d < 3; ++d) base[d] = grid.axis_coordinate(d, c[d]) - double(w.lo[d] + grid.first(d));
  if (base.cwiseAbs().maxCoeff() > 0x1p40) {  // absurdly far from the mesh: one point
    bool flagged = false;
    outside(ctx, s, p, p.volume, grid.nearest(c), flagged, policy);
    return;
  }
  float rows[9];
  kernels::rotation_rows(R, rows);
  if (deposit_by_octants(ctx, s, p, t, rows, w, base, [&](std::int64_t cell, double v) { s.deposits.push_back({cell, v}); }))
    return;
  const Eigen::Matrix3d to_cells = inv_h.asDiagonal() * R * r;
  if (w.size() > (std::size_t(1) << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "particle " + std::to_string(p.index) + " spans " + std::to_string(w.size()) +
                    " cells (more than 2^26); use cells no smaller than about 1/400 of the particle diameter");
  const std::size_t n = t.size(), cells = w.size();
  s.local_cells.resize(n);
  kernels::locate_in_block(t, base, to_cells, w.m, s.local_cells.data());
  // Four interleaved partial sums per cell: consecutive sub-elements often hit the same
  // cell, and one sum would chain every add through memory.
  s.lanes.assign(4 * cells, 0.0);
  const double* f = t.fractions.data();
  const std::int32_t* cell = s.local_cells.data();
  double* lanes = s.lanes.data();
  for (std::size_t q = 0; q < n; ++q) lanes[4 * std::size_t(cell[q]) + (q & 3)] += f[q];
  s.window.resize(cells);
  for (std::size_t c = 0; c < cells; ++c)
    s.window[c] = p.volume * ((lanes[4 * c] + lanes[4 * c + 1]) + (lanes[4 * c + 2] + lanes[4 * c + 3]));
  emit_window(ctx, s, p, w, policy);
}

}  // namespace vfe::detail

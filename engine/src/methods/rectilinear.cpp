#include "methods/rectilinear.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>

#include <algorithm>
#include <cmath>

namespace vfe::detail {

namespace {

bool periodic(const RectilinearContext& ctx, int d) { return (ctx.opts.periodic >> d) & 1u; }

double length(const RectilinearGrid& g, int d) { return g.nodes(d).back() - g.nodes(d).front(); }

/// x moved into [lo, hi) along the periodic axes.
Eigen::Vector3d wrap(const RectilinearContext& ctx, Eigen::Vector3d x) {
  for (int d = 0; d < 3; ++d) {
    if (!periodic(ctx, d)) continue;
    const double lo = ctx.grid.nodes(d).front(), len = length(ctx.grid, d);
    double u = std::fmod(x[d] - lo, len);
    if (u < 0) u += len;
    if (!(u < len)) u = 0;
    x[d] = lo + u;
  }
  return x;
}

/// Node g of axis d, continued periodically past the ends (g may be < 0 or > n).
double node(const RectilinearGrid& grid, int d, std::int64_t g) {
  const std::int64_t n = grid.cells()[d];
  const std::int64_t q = g >= 0 ? g / n : -((-g + n - 1) / n);
  return grid.nodes(d)[static_cast<std::size_t>(g - q * n)] + double(q) * length(grid, d);
}

/// Cell coordinate of x along axis d, continued periodically (may be < 0 or >= n).
std::int64_t periodic_axis_index(const RectilinearGrid& grid, int d, double x) {
  const std::int64_t n = grid.cells()[d];
  const double lo = grid.nodes(d).front(), len = length(grid, d);
  const double turns = std::floor((x - lo) / len);
  std::int64_t i = grid.axis_index(d, x - turns * len);
  i = std::clamp<std::int64_t>(i, 0, n - 1);  // round-off at the ends
  return i + static_cast<std::int64_t>(turns) * n;
}

void outside_rect(const RectilinearContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
                  bool& flagged) {
  if (!flagged) {
    flagged = true;
    ++s.outside_particles;
  }
  switch (ctx.opts.outside) {
    case Outside::nearest: s.add(ctx.grid.nearest(at), volume); break;
    case Outside::centre: s.add(ctx.grid.nearest(p.centre), volume); break;
    case Outside::drop: s.add(ctx.grid.cell_count(), volume); break;  // the dropped-volume slot
    case Outside::error: s.first_error = std::min(s.first_error, p.index); break;
  }
}

void deposit_at(const RectilinearContext& ctx, Scratch& s, const Particle& p, const Eigen::Vector3d& x, double v,
                bool& flagged) {
  const Eigen::Vector3d w = wrap(ctx, x);
  if (const std::int64_t cell = ctx.grid.locate(w); cell >= 0)
    s.add(cell, v);
  else
    outside_rect(ctx, s, p, v, w, flagged);
}

/// The one cell wholly holding the ball (c, r), or -1.
std::int64_t one_cell(const RectilinearContext& ctx, const Eigen::Vector3d& c, double r) {
  if (!ctx.opts.fast_path) return -1;
  std::int64_t idx[3];
  for (int d = 0; d < 3; ++d) {
    const std::int64_t lo = ctx.grid.axis_index(d, c[d] - r);
    if (lo != ctx.grid.axis_index(d, c[d] + r) || lo < 0 || lo >= ctx.grid.cells()[d]) return -1;
    idx[d] = lo;
  }
  return ctx.grid.index(idx[0], idx[1], idx[2]);
}

void exact(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const RectilinearGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  std::int64_t lo[3], hi[3];
  bool empty = false;
  for (int d = 0; d < 3; ++d) {
    if (periodic(ctx, d)) {
      lo[d] = periodic_axis_index(grid, d, c[d] - r);
      hi[d] = periodic_axis_index(grid, d, c[d] + r);
      continue;
    }
    lo[d] = std::max<std::int64_t>(grid.axis_index(d, c[d] - r), 0);
    hi[d] = std::min<std::int64_t>(grid.axis_index(d, c[d] + r), grid.cells()[d] - 1);
    if (lo[d] > hi[d]) empty = true;
  }
  bool flagged = false;
  if (empty) {
    outside_rect(ctx, s, p, p.volume, c, flagged);
    return;
  }
  int m[3];
  for (int d = 0; d < 3; ++d) {
    m[d] = static_cast<int>(hi[d] - lo[d] + 1);
    s.nodes[d].resize(static_cast<std::size_t>(m[d] + 1));
    for (int i = 0; i <= m[d]; ++i) s.nodes[d][i] = node(grid, d, lo[d] + i);
  }
  s.sub_elements += std::int64_t(m[0]) * m[1] * m[2];
  auto cell_of = [&](int d, std::int64_t g) {
    const std::int64_t n = grid.cells()[d];
    return ((g % n) + n) % n;
  };
  double inside = 0;
  kernels::sphere_patch_overlaps(c, r, s.nodes[0].data(), m[0], s.nodes[1].data(), m[1], s.nodes[2].data(), m[2],
                                 s.orthant, s.patch, [&](int i, int j, int k, double v) {
                                   s.add(grid.index(cell_of(0, lo[0] + i), cell_of(1, lo[1] + j),
                                                    cell_of(2, lo[2] + k)),
                                         v);
                                   inside += v;
                                 });
  const double rest = p.volume - inside;  // beyond the mesh, up to round-off
  if (rest > 1e-12 * p.volume) outside_rect(ctx, s, p, rest, c, flagged);
}

/// pmm: the sub-elements located within the window of cells the particle can reach (per
/// axis a short search among the window's nodes), summed per window cell, then emitted
/// once per cell; window cells beyond a non-periodic side are outside the mesh.
void deposit_template(const RectilinearContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                      const Eigen::Matrix3d& rotation) {
  const RectilinearGrid& grid = ctx.grid;
  const double half = p.radius * t.reach;
  std::int64_t lo[3];
  int m[3];
  for (int d = 0; d < 3; ++d) {
    const std::int64_t n = grid.cells()[d];
    std::int64_t a, b;
    if (periodic(ctx, d)) {
      a = periodic_axis_index(grid, d, p.centre[d] - half);
      b = periodic_axis_index(grid, d, p.centre[d] + half);
    } else {  // -1 and n stand for everything beyond either side
      a = std::clamp<std::int64_t>(grid.axis_index(d, p.centre[d] - half), -1, n);
      b = std::clamp<std::int64_t>(grid.axis_index(d, p.centre[d] + half), -1, n);
    }
    lo[d] = a;
    m[d] = static_cast<int>(b - a + 1);
    // The window's inner nodes: the boundaries between its cells.
    s.nodes[d].resize(static_cast<std::size_t>(std::max(m[d] - 1, 0)));
    for (int i = 1; i < m[d]; ++i) s.nodes[d][i - 1] = node(grid, d, a + i);
  }
  const std::size_t cells = std::size_t(m[0]) * std::size_t(m[1]) * std::size_t(m[2]);
  s.window.assign(cells, 0.0);
  const Eigen::Matrix3d transform = rotation * p.radius;
  for (std::size_t q = 0; q < t.size(); ++q) {
    const Eigen::Vector3d x = p.centre + transform * t.points[q];
    std::size_t local = 0, stride = 1;
    for (int d = 0; d < 3; ++d) {
      const auto& inner = s.nodes[d];
      const auto i = static_cast<std::size_t>(std::upper_bound(inner.begin(), inner.end(), x[d]) - inner.begin());
      local += i * stride;
      stride *= static_cast<std::size_t>(m[d]);
    }
    s.window[local] += t.fractions[q];
  }
  bool flagged = false;
  std::size_t local = 0;
  for (int k = 0; k < m[2]; ++k)
    for (int j = 0; j < m[1]; ++j)
      for (int i = 0; i < m[0]; ++i, ++local) {
        const double v = p.volume * s.window[local];
        if (v == 0.0) continue;
        const std::int64_t g[3] = {lo[0] + i, lo[1] + j, lo[2] + k};
        std::int64_t c[3];
        bool out = false;
        for (int d = 0; d < 3; ++d) {
          const std::int64_t n = grid.cells()[d];
          if (periodic(ctx, d)) {
            c[d] = ((g[d] % n) + n) % n;
          } else {
            out |= g[d] < 0 || g[d] >= n;
            c[d] = std::clamp<std::int64_t>(g[d], 0, n - 1);
          }
        }
        const std::int64_t cell = grid.index(c[0], c[1], c[2]);
        if (!out) {
          s.add(cell, v);
          continue;
        }
        if (!flagged) {
          flagged = true;
          ++s.outside_particles;
        }
        switch (ctx.opts.outside) {
          case Outside::nearest: s.add(cell, v); break;
          case Outside::centre: s.add(grid.nearest(p.centre), v); break;
          case Outside::drop: s.add(grid.cell_count(), v); break;
          case Outside::error: s.first_error = std::min(s.first_error, p.index); break;
        }
      }
}

}  // namespace

void rectilinear_particle(const RectilinearContext& ctx, Scratch& s, const Particle& p,
                          const kernels::ParticleTemplate* t, const Eigen::Vector3d& centroid) {
  const bool is_exact = ctx.opts.method == Method::exact;
  const double reach = is_exact || !t ? 1.0 : t->reach;
  if (is_exact || t) {
    if (t) s.count_grid(static_cast<std::int64_t>(t->size()));
    if (const std::int64_t cell = one_cell(ctx, p.centre, p.radius * reach); cell >= 0) {
      ++s.fast_path;
      s.add(cell, p.volume);
      return;
    }
  }
  if (is_exact) {
    exact(ctx, s, p);
    return;
  }
  const Eigen::Matrix3d rotation = particle_rotation(ctx.opts, p);
  bool flagged = false;
  if (!t) {  // direct
    ++s.sub_elements;
    deposit_at(ctx, s, p, p.centre + p.radius * (rotation * centroid), p.volume, flagged);
    return;
  }
  s.sub_elements += static_cast<std::int64_t>(t->size());
  deposit_template(ctx, s, p, *t, rotation);
}

}  // namespace vfe::detail

#include "methods/rectilinear.hpp"

#include <vfe/kernels/big_particle.hpp>
#include <vfe/kernels/gaussian.hpp>
#include <vfe/kernels/porous_cube.hpp>
#include <vfe/kernels/separable.hpp>
#include <vfe/kernels/sphere_box_overlap.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace vfe::detail {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool periodic(const RectilinearContext& ctx, int d) { return (ctx.opts.periodic >> d) & 1u; }

double length(const RectilinearGrid& g, int d) { return g.nodes(d).back() - g.nodes(d).front(); }

/// A window of cells around a particle: per axis the cells lo[d] .. lo[d] + m[d] - 1, where
/// on a non-periodic axis -1 and n stand for everything beyond either side and on a periodic
/// axis the cells continue past the ends (wrapped when deposited).
struct GradedWindow {
  std::int64_t lo[3];
  int m[3];
  std::size_t size() const { return std::size_t(m[0]) * std::size_t(m[1]) * std::size_t(m[2]); }
};

/// Window coordinate of x along axis d (clamped to the virtual cells on non-periodic axes).
std::int64_t window_index(const RectilinearContext& ctx, int d, double x) {
  if (periodic(ctx, d)) return periodic_axis_index(ctx.grid, d, x);
  return std::clamp<std::int64_t>(ctx.grid.axis_index(d, x), -1, ctx.grid.cells()[d]);
}

GradedWindow make_window(const RectilinearContext& ctx, const Eigen::Vector3d& c, const Eigen::Vector3d& half,
                   std::int64_t particle) {
  GradedWindow w;
  for (int d = 0; d < 3; ++d) {
    w.lo[d] = window_index(ctx, d, c[d] - half[d]);
    const std::int64_t m = window_index(ctx, d, c[d] + half[d]) - w.lo[d] + 1;
    if (m > (1 << 20))
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(particle) + " spans " + std::to_string(m) +
                                                  " cells along one periodic axis (more than 2^20); its footprint "
                                                  "wraps the periodic grid many times: use a larger periodic grid");
    w.m[d] = static_cast<int>(m);
  }
  if (w.size() > (std::size_t(1) << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(particle) + " spans " + std::to_string(w.size()) +
                                                " cells (more than 2^26); use cells no smaller than about 1/400 of the "
                                                "particle diameter");
  return w;
}

/// Node k of window w along axis d (k = 0 .. m): the grid's nodes, -inf/+inf as the outer
/// bounds of the virtual cells, continued on periodic axes.
double window_node(const RectilinearContext& ctx, const GradedWindow& w, int d, int k) {
  const std::int64_t g = w.lo[d] + k;
  if (periodic(ctx, d)) return periodic_node(ctx.grid, d, g);
  if (g < 0) return -kInf;
  if (g > ctx.grid.cells()[d]) return kInf;
  return ctx.grid.nodes(d)[static_cast<std::size_t>(g)];
}

/// The mesh cell of window cell g along axis d, and whether it is beyond the mesh (then the
/// nearest cell along that axis).
std::int64_t window_cell(const RectilinearContext& ctx, int d, std::int64_t g, bool& out) {
  const std::int64_t n = ctx.grid.cells()[d];
  if (periodic(ctx, d)) return ((g % n) + n) % n;
  out |= g < 0 || g >= n;
  return std::clamp<std::int64_t>(g, 0, n - 1);
}

void outside(const RectilinearContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
             Outside policy, bool& flagged) {
  apply_outside(s, p, volume, policy, ctx.grid.cell_count(), flagged, [&] { return ctx.grid.nearest(at); },
                [&] { return ctx.grid.nearest(p.centre); });
}

/// s.window (volume per window cell, times scale) into deposits; cells beyond the mesh go
/// through the outside policy with their nearest cell.
void emit_window(const RectilinearContext& ctx, Scratch& s, const Particle& p, const GradedWindow& w, double scale,
                 Outside policy) {
  bool flagged = false;
  std::size_t local = 0;
  for (int k = 0; k < w.m[2]; ++k)
    for (int j = 0; j < w.m[1]; ++j)
      for (int i = 0; i < w.m[0]; ++i, ++local) {
        const double v = scale * s.window[local];
        if (v == 0.0) continue;
        bool out = false;
        const std::int64_t cell = ctx.grid.index(window_cell(ctx, 0, w.lo[0] + i, out),
                                                 window_cell(ctx, 1, w.lo[1] + j, out),
                                                 window_cell(ctx, 2, w.lo[2] + k, out));
        if (!out)
          s.add(cell, v);
        else
          apply_outside(s, p, v, policy, ctx.grid.cell_count(), flagged, [&] { return cell; },
                        [&] { return ctx.grid.nearest(p.centre); });
      }
}


bool take_fast_path(const RectilinearContext& ctx, Scratch& s, const Particle& p, const Eigen::Vector3d& half) {
  const std::int64_t cell = rectilinear_one_cell(ctx, p.centre, half);
  if (cell < 0) return false;
  ++s.fast_path;
  s.add(cell, p.volume);
  return true;
}

/// Template points (scaled by the radius, rotated) located within the particle's window of
/// cells (per axis a short search among the window's inner nodes), summed per window cell,
/// then emitted once per cell.
void deposit_points(const RectilinearContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                    const Eigen::Matrix3d& rotation, Outside policy) {
  s.count_grid(static_cast<std::int64_t>(t.size()));
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(p.radius * t.reach);
  if (take_fast_path(ctx, s, p, half)) return;
  s.sub_elements += static_cast<std::int64_t>(t.size());
  const GradedWindow w = make_window(ctx, p.centre, half, p.index);
  for (int d = 0; d < 3; ++d) {  // the window's inner nodes: the boundaries between its cells
    s.nodes[d].resize(static_cast<std::size_t>(std::max(w.m[d] - 1, 0)));
    for (int i = 1; i < w.m[d]; ++i) s.nodes[d][i - 1] = window_node(ctx, w, d, i);
  }
  s.window.assign(w.size(), 0.0);
  const Eigen::Matrix3d transform = rotation * p.radius;
  for (std::size_t q = 0; q < t.size(); ++q) {
    const Eigen::Vector3d x = p.centre + transform * t.points[q];
    std::size_t local = 0, stride = 1;
    for (int d = 0; d < 3; ++d) {
      const auto& inner = s.nodes[d];
      const auto i = static_cast<std::size_t>(std::upper_bound(inner.begin(), inner.end(), x[d]) - inner.begin());
      local += i * stride;
      stride *= static_cast<std::size_t>(w.m[d]);
    }
    s.window[local] += t.fractions[q];
  }
  emit_window(ctx, s, p, w, p.volume, policy);
}

/// The per-axis weights in s.axis[d] (w.m[d] each) times the volume into the window.
void deposit_separable(const RectilinearContext& ctx, Scratch& s, const Particle& p, const GradedWindow& w) {
  s.window.assign(w.size(), 0.0);
  const int m0 = w.m[0], m1 = w.m[1];
  kernels::separable_deposit(s.axis[0].data(), w.m[0], s.axis[1].data(), w.m[1], s.axis[2].data(), w.m[2], p.volume,
                             [&s, m0, m1](int i, int j, int k, double v) {
                               s.window[static_cast<std::size_t>(i + m0 * (j + m1 * k))] = v;
                             });
  emit_window(ctx, s, p, w, 1.0, p.outside);
}

/// A separable kernel of half-width `half`: axis_weights(centre, nodes, m, out) per axis over
/// the window's nodes in real coordinates.
template <class AxisWeights>
void spread_separable(const RectilinearContext& ctx, Scratch& s, const Particle& p, const Eigen::Vector3d& half,
                      AxisWeights&& axis_weights) {
  if (take_fast_path(ctx, s, p, half)) return;
  const GradedWindow w = make_window(ctx, p.centre, half, p.index);
  for (int d = 0; d < 3; ++d) {
    s.nodes[d].resize(static_cast<std::size_t>(w.m[d] + 1));
    for (int k = 0; k <= w.m[d]; ++k) s.nodes[d][k] = window_node(ctx, w, d, k);
    s.axis[d].resize(static_cast<std::size_t>(w.m[d]));
    axis_weights(p.centre[d], s.nodes[d].data(), w.m[d], s.axis[d].data());
  }
  s.sub_elements += static_cast<std::int64_t>(w.size());
  deposit_separable(ctx, s, p, w);
}

/// Centre of window cell g along axis d: the cell's midpoint; virtual cells beyond a
/// non-periodic side continue with the end cell's size.
double cell_centre_axis(const RectilinearContext& ctx, int d, std::int64_t g) {
  if (periodic(ctx, d)) return 0.5 * (periodic_node(ctx.grid, d, g) + periodic_node(ctx.grid, d, g + 1));
  const auto& x = ctx.grid.nodes(d);
  const std::int64_t n = ctx.grid.cells()[d];
  if (g < 0) return x[0] - (double(-g) - 0.5) * (x[1] - x[0]);
  if (g >= n) return x[n] + (double(g - n) + 0.5) * (x[n] - x[n - 1]);
  return 0.5 * (x[g] + x[g + 1]);
}

}  // namespace

std::int64_t rectilinear_one_cell(const RectilinearContext& ctx, const Eigen::Vector3d& c, const Eigen::Vector3d& half) {
  if (!ctx.opts.fast_path) return -1;
  std::int64_t idx[3];
  for (int d = 0; d < 3; ++d) {
    const std::int64_t lo = ctx.grid.axis_index(d, c[d] - half[d]);
    if (lo != ctx.grid.axis_index(d, c[d] + half[d]) || lo < 0 || lo >= ctx.grid.cells()[d]) return -1;
    idx[d] = lo;
  }
  return ctx.grid.index(idx[0], idx[1], idx[2]);
}

double periodic_node(const RectilinearGrid& grid, int d, std::int64_t g) {
  const std::int64_t n = grid.cells()[d];
  const std::int64_t q = g >= 0 ? g / n : -((-g + n - 1) / n);
  return grid.nodes(d)[static_cast<std::size_t>(g - q * n)] + double(q) * length(grid, d);
}

std::int64_t periodic_axis_index(const RectilinearGrid& grid, int d, double x) {
  const std::int64_t n = grid.cells()[d];
  const double lo = grid.nodes(d).front(), len = length(grid, d);
  const double turns = std::clamp(std::floor((x - lo) / len), -double(1LL << 40), double(1LL << 40));
  std::int64_t i = grid.axis_index(d, x - turns * len);
  i = std::clamp<std::int64_t>(i, 0, n - 1);  // round-off at the ends
  return i + static_cast<std::int64_t>(turns) * n;
}


Eigen::Vector3d rectilinear_wrap(const RectilinearGrid& grid, unsigned periodic_axes, Eigen::Vector3d x) {
  for (int d = 0; d < 3; ++d) {
    if (!((periodic_axes >> d) & 1u)) continue;
    const double lo = grid.nodes(d).front(), len = length(grid, d);
    double u = std::fmod(x[d] - lo, len);
    if (u < 0) u += len;
    if (!(u < len)) u = 0;
    x[d] = lo + u;
  }
  return x;
}

void rectilinear_direct(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  ++s.sub_elements;
  const Eigen::Vector3d at =
      p.shaped ? rectilinear_wrap(ctx.grid, ctx.opts.periodic,
                                  p.centre + p.radius * (particle_rotation(ctx.opts, p) * p.centroid))
               : p.centre;
  bool flagged = false;
  if (const std::int64_t cell = ctx.grid.locate(at); cell >= 0)
    s.add(cell, p.volume);
  else
    outside(ctx, s, p, p.volume, at, p.outside, flagged);
}

void rectilinear_pmm(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const kernels::ParticleTemplate& t =
      p.shape_template ? *p.shape_template
                       : ctx.bank.template_for(2 * p.radius, ctx.grid.cell_volume(ctx.grid.nearest(p.centre)), s.template_memo);
  deposit_points(ctx, s, p, t, particle_rotation(ctx.opts, p), p.outside);
}

void rectilinear_divided(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  // As in CFDEM: never rotated, and a point in no cell goes to the particle's own cell.
  const Outside policy = p.outside == Outside::nearest ? Outside::centre : p.outside;
  deposit_points(ctx, s, p, ctx.divided, Eigen::Matrix3d::Identity(), policy);
}

BallBox ball_box(const RectilinearContext& ctx, const Eigen::Vector3d& c, double r) {
  const RectilinearGrid& grid = ctx.grid;
  BallBox box;
  bool one = ctx.opts.fast_path;
  for (int d = 0; d < 3; ++d) {
    const std::int64_t lo = grid.axis_index(d, c[d] - r), hi = grid.axis_index(d, c[d] + r);
    one &= lo == hi && lo >= 0 && lo < grid.cells()[d];  // rectilinear_one_cell's test
    box.lo[d] = lo, box.hi[d] = hi;
  }
  if (one) {
    box.one_cell = grid.index(box.lo[0], box.lo[1], box.lo[2]);
    return box;
  }
  for (int d = 0; d < 3; ++d)
    if (periodic(ctx, d)) {
      box.lo[d] = periodic_axis_index(grid, d, c[d] - r);
      box.hi[d] = periodic_axis_index(grid, d, c[d] + r);
    }
  return box;
}

void rectilinear_exact(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const BallBox box = ball_box(ctx, p.centre, p.radius);
  if (box.one_cell >= 0) {
    ++s.fast_path;
    s.add(box.one_cell, p.volume);
    return;
  }
  rectilinear_exact_in_box(ctx, s, p, box);
}

void rectilinear_exact_in_box(const RectilinearContext& ctx, Scratch& s, const Particle& p, const BallBox& box) {
  const RectilinearGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  std::int64_t lo[3], hi[3];
  bool empty = false;
  for (int d = 0; d < 3; ++d) {
    if (periodic(ctx, d)) {
      lo[d] = box.lo[d], hi[d] = box.hi[d];
      if (hi[d] - lo[d] >= (1 << 20))
        throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(p.index) +
                                                    " wraps the periodic grid more than 2^20 cells; use a larger "
                                                    "periodic grid");
      continue;
    }
    lo[d] = std::max<std::int64_t>(box.lo[d], 0);
    hi[d] = std::min<std::int64_t>(box.hi[d], grid.cells()[d] - 1);
    if (lo[d] > hi[d]) empty = true;
  }
  bool flagged = false;
  if (empty) {
    outside(ctx, s, p, p.volume, c, p.outside, flagged);
    return;
  }
  int m[3];
  for (int d = 0; d < 3; ++d) {
    m[d] = static_cast<int>(hi[d] - lo[d] + 1);
    s.nodes[d].resize(static_cast<std::size_t>(m[d] + 1));
    for (int i = 0; i <= m[d]; ++i) s.nodes[d][i] = periodic_node(grid, d, lo[d] + i);
  }
  if (double(m[0]) * m[1] * m[2] > double(1 << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(p.index) +
                                                " overlaps more than 2^26 cells; use cells no smaller than about "
                                                "1/400 of the particle diameter");
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
  if (rest > 1e-12 * p.volume) outside(ctx, s, p, rest, c, p.outside, flagged);
}

void rectilinear_gaussian(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const double sigma = ctx.opts.sigma * 2.0 * p.radius;
  spread_separable(ctx, s, p, Eigen::Vector3d::Constant(kernels::kGaussianCut * sigma),
                   [sigma](double centre, const double* nodes, int m, double* out) {
                     kernels::gaussian_axis_weights(centre, sigma, nodes, m, out);
                   });
}

void rectilinear_porous_cube(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const double half_side = ctx.opts.gamma * p.radius;
  spread_separable(ctx, s, p, Eigen::Vector3d::Constant(half_side),
                   [half_side](double centre, const double* nodes, int m, double* out) {
                     kernels::interval_axis_weights(centre - half_side, centre + half_side, nodes, m, out);
                   });
}

void rectilinear_trilinear(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  // Per axis the two cells whose centres enclose the particle's centre (the grid's cell
  // midpoints, continued beyond the ends), with linear weights between those centres.
  GradedWindow w;
  for (int d = 0; d < 3; ++d) {
    const double x = p.centre[d];
    std::int64_t g = window_index(ctx, d, x);
    if (x < cell_centre_axis(ctx, d, g)) --g;  // now centre(g) <= x (or g below the virtual cell)
    const std::int64_t n = ctx.grid.cells()[d];
    double w1 = 0;
    if (!periodic(ctx, d) && g < -1) {
      g = -1;  // beyond the lower virtual cell's centre: all to it
    } else if (!periodic(ctx, d) && g >= n) {
      g = n;
    } else {
      const double a = cell_centre_axis(ctx, d, g), b = cell_centre_axis(ctx, d, g + 1);
      w1 = std::clamp((x - a) / (b - a), 0.0, 1.0);
    }
    w.lo[d] = g;
    w.m[d] = w1 > 0 ? 2 : 1;
    s.axis[d].assign(static_cast<std::size_t>(w.m[d]), 0.0);
    s.axis[d][0] = 1.0 - w1;
    if (w.m[d] == 2) s.axis[d][1] = w1;
  }
  s.sub_elements += 8;
  deposit_separable(ctx, s, p, w);
}

void rectilinear_big_particle(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  const Eigen::Vector3d& c = p.centre;
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(p.radius);
  if (take_fast_path(ctx, s, p, half)) return;  // only this cell's centre can lie within
  // Window cells whose centres can lie within the particle, per axis; beyond a non-periodic
  // side the virtual cells continue with the end cell's size, each its own centre.
  std::int64_t g0[3];
  int m[3];
  for (int d = 0; d < 3; ++d) {
    const double h_lo = ctx.grid.nodes(d)[1] - ctx.grid.nodes(d)[0];
    const std::int64_t n = ctx.grid.cells()[d];
    const double h_hi = ctx.grid.nodes(d)[n] - ctx.grid.nodes(d)[n - 1];
    const double extent = std::max(p.radius / std::min(h_lo, h_hi), 1.0);
    if (!(extent < double(1 << 20)))
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(p.index) +
                                                  ": big_particle would test more than 2^20 cell centres per axis; "
                                                  "use cells no smaller than about 1/400 of the particle diameter");
    std::int64_t a;
    if (periodic(ctx, d)) {
      a = periodic_axis_index(ctx.grid, d, c[d] - p.radius);
    } else {
      a = ctx.grid.axis_index(d, c[d] - p.radius);
      if (a < 0) a = -static_cast<std::int64_t>(std::ceil((ctx.grid.nodes(d)[0] - (c[d] - p.radius)) / h_lo));
    }
    while (cell_centre_axis(ctx, d, a) < c[d] - p.radius) ++a;
    std::int64_t b = a - 1;
    while (cell_centre_axis(ctx, d, b + 1) <= c[d] + p.radius) ++b;
    g0[d] = a;
    m[d] = static_cast<int>(std::max<std::int64_t>(b - a + 1, 0));
    s.nodes[d].resize(static_cast<std::size_t>(m[d]));
    for (int i = 0; i < m[d]; ++i) s.nodes[d][i] = cell_centre_axis(ctx, d, a + i);
  }
  if (double(m[0]) * m[1] * m[2] > double(1 << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(p.index) +
                                                ": big_particle would test more than 2^26 cell centres; use cells no "
                                                "smaller than about 1/400 of the particle diameter");
  s.sub_elements += std::int64_t(m[0]) * m[1] * m[2];
  bool flagged = false;
  const std::int64_t count = kernels::big_particle_deposit(
      c, p.radius, p.volume, s.nodes[0].data(), m[0], s.nodes[1].data(), m[1], s.nodes[2].data(), m[2],
      [&](int i, int j, int k, double v) {
        bool out = false;
        const std::int64_t cell = ctx.grid.index(window_cell(ctx, 0, g0[0] + i, out), window_cell(ctx, 1, g0[1] + j, out),
                                                 window_cell(ctx, 2, g0[2] + k, out));
        if (!out)
          s.add(cell, v);
        else
          apply_outside(s, p, v, p.outside, ctx.grid.cell_count(), flagged, [&] { return cell; },
                        [&] { return ctx.grid.nearest(p.centre); });
      });
  if (count > 0) return;
  // No cell centre within the particle: its own cell.
  if (const std::int64_t cell = ctx.grid.locate(c); cell >= 0)
    s.add(cell, p.volume);
  else
    outside(ctx, s, p, p.volume, c, p.outside, flagged);
}

}  // namespace vfe::detail

// method=auto (methods/hybrid.hpp): per sphere the fast path when the ball lies in one
// cell, else pmm at the size particle_grid gives it or the exact overlap, whichever the
// cost model of the mesh kind finds cheaper.
#include "methods/hybrid.hpp"

#include <algorithm>

namespace vfe::detail {

namespace {

// Measured with `build/release/vfe_bench_auto_costs` (one thread, Release build;
// docs/performance.md, "method=auto"; the Cartesian constants the mean of two runs, after
// the octant count, the one-pass direct and exact's octant call): whole computes of pmm and exact on groups of random
// spheres per mesh kind, each path's time per sphere fitted to its mean work by least
// squares, every constant >= 0 (a work measure that others explain gets 0).
constexpr GridCosts kCartesian{36, 2.5, 0.19, 106, 56, 22.4, 11.2};
constexpr GridCosts kRectilinear{290, 8.8, 8.8, 69, 47, 0, 0};
constexpr PolyCosts kPolyhedral{0, 24.5, 298, 0, 0, 808, 42};

/// Cells from lo to hi along an axis of n cells, clamped to the mesh unless it wraps (exact's box of cells).
std::int64_t cells_of_box(std::int64_t lo, std::int64_t hi, std::int64_t n, bool periodic) {
  if (!periodic) {
    lo = std::max<std::int64_t>(lo, 0);
    hi = std::min<std::int64_t>(hi, n - 1);
  }
  return std::max<std::int64_t>(hi - lo + 1, 0);
}

}  // namespace

const GridCosts& cartesian_costs() { return kCartesian; }
const GridCosts& rectilinear_costs() { return kRectilinear; }
const PolyCosts& polyhedral_costs() { return kPolyhedral; }

PathCosts path_costs(const Context& ctx, Scratch& s, const Particle& p) {
  PathCosts k;
  const CartesianGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  k.fast_cell = single_cell(ctx, c, Eigen::Vector3d::Constant(r));
  if ((k.fast = k.fast_cell >= 0)) return k;
  const GridCosts& m = cartesian_costs();
  const kernels::ParticleTemplate& t = ctx.template_for(p, s);
  k.pmm_template = &t;
  const Window w = make_window(grid, c, Eigen::Vector3d::Constant(r * t.reach));
  bool in_mesh = true, small = true;
  for (int d = 0; d < 3; ++d) {
    small &= w.m[d] <= 2;
    in_mesh &= grid.cell_axis(d, w.lo[d]) >= 0 && grid.cell_axis(d, w.lo[d] + w.m[d] - 1) >= 0;
  }
  if (w.size() == 1 && in_mesh && ctx.opts.fast_path) {
    k.pmm = 0;  // pmm's own fast path: its template lies in one cell
  } else {
    k.pmm_points = static_cast<std::int64_t>(t.size());
    k.counted = small && in_mesh && ctx.opts.fast_path && !t.split_points.empty();
    k.pmm = m.pmm_particle + double(k.pmm_points) * (k.counted ? m.pmm_counted : m.pmm_point);
  }
  double cells = 1;
  // exact's octant call serves a ball over at most two cells per axis, periodic or beyond
  // the mesh alike (in global cell units: a rank's block decides as the whole grid does).
  k.exact_octants = true;
  for (int d = 0; d < 3; ++d) {
    const std::int64_t lo = grid.axis_index(d, c[d] - r), hi = grid.axis_index(d, c[d] + r);
    cells *= double(cells_of_box(lo, hi, grid.cells()[d], grid.periodic(d)));
    k.exact_octants &= hi - lo <= 1;
  }
  k.exact_cells = static_cast<std::int64_t>(std::min(cells, 1e18));
  k.exact = k.exact_octants ? m.exact_octant_particle + cells * m.exact_octant_cell
                            : m.exact_particle + cells * m.exact_cell;
  return k;
}

PathCosts path_costs(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  PathCosts k;
  const RectilinearGrid& grid = ctx.grid;
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius;
  k.box = ball_box(ctx, c, r);
  k.fast_cell = k.box.one_cell;
  if ((k.fast = k.fast_cell >= 0)) return k;
  const GridCosts& m = rectilinear_costs();
  double cells = 1;
  for (int d = 0; d < 3; ++d)
    cells *= double(cells_of_box(k.box.lo[d], k.box.hi[d], grid.cells()[d], (ctx.opts.periodic >> d) & 1u));
  k.exact_cells = static_cast<std::int64_t>(std::min(cells, 1e18));
  k.exact = m.exact_particle + cells * m.exact_cell;
  // Locating by search costs enough that exact usually wins: when pmm with the bank's
  // smallest template (its first) cannot be cheaper, the template is not looked up.
  const double fewest = ctx.bank.templates.empty() ? 1.0 : double(ctx.bank.templates.front()->size());
  if (!(m.pmm_particle + fewest * m.pmm_point < k.exact)) {
    k.pmm_points = static_cast<std::int64_t>(fewest);
    k.pmm = m.pmm_particle + fewest * m.pmm_point;
    return k;
  }
  const kernels::ParticleTemplate& t = ctx.bank.template_for(2 * r, grid.cell_volume(grid.nearest(c)), s.template_memo);
  k.pmm_template = &t;
  k.pmm_points = static_cast<std::int64_t>(t.size());
  k.pmm = m.pmm_particle + double(k.pmm_points) * m.pmm_point;
  return k;
}

PathCosts path_costs(const PolyContext& ctx, Scratch& s, const Particle& p, bool full) {
  PathCosts k;
  const PolyMesh& mesh = ctx.locator->mesh();
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius, r2 = r * r;
  const std::int64_t centre_cell = ctx.locator->locate(c);
  k.centre_cell = centre_cell;
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, c, r)) {
    k.fast = true;
    k.fast_cell = centre_cell;
    return k;
  }
  const PolyCosts& m = polyhedral_costs();
  const std::int64_t cell = centre_cell >= 0 ? centre_cell : ctx.locator->nearest_cell(c);
  const kernels::ParticleTemplate& t = ctx.bank.template_for(2 * r, mesh.cell_volume(cell), s.template_memo);
  k.pmm_template = &t;
  // exact's cells: those its walk finds, or where a boundary face is in reach the hash's
  // near the ball.
  std::uint64_t particle = 0;
  if (centre_cell >= 0 && walk_ball_cells(mesh, s, c, r, centre_cell, particle)) {
    k.walked = particle;
  } else {
    const Eigen::Vector3d half = Eigen::Vector3d::Constant(r);
    ctx.locator->hash().cells_in_box(Eigen::AlignedBox3d(c - half, c + half), s.candidate_cells);
  }
  const double candidates = double(s.candidate_cells.size());
  k.exact_cells = static_cast<std::int64_t>(s.candidate_cells.size());
  k.pmm_points = static_cast<std::int64_t>(t.size());
  k.pmm = m.pmm_particle + double(k.pmm_points) * m.pmm_point + candidates * m.pmm_candidate;
  k.exact = m.exact_particle + candidates * m.exact_candidate;
  // polymesh_exact's work per candidate: nothing beyond the ball's reach or inside it, the
  // closed form on a box, otherwise the located sum over the faces whose planes the ball
  // reaches (about linear in their points; a warped face is the fan of its triangles).
  const double reach = r + mesh.location_tolerance();
  for (const std::int64_t cand : s.candidate_cells) {
    if (!full && k.exact > k.pmm) break;
    const Eigen::AlignedBox3d& box = mesh.cell_bounds(cand);
    if (box.squaredExteriorDistance(c) >= r2) continue;
    if ((box.min() - c).cwiseAbs().cwiseMax((box.max() - c).cwiseAbs()).squaredNorm() <= r2) continue;
    Eigen::AlignedBox3d cell_box;
    if (cached_cell_is_box(mesh, s, cand, cell_box)) {
      ++k.box_cells;
      k.exact += m.exact_box_cell;
      continue;
    }
    std::int64_t points = 0;
    for (const std::int64_t f : mesh.cell_faces(cand))
      if (face_plane_in_reach(mesh, f, c, reach))
        points += static_cast<std::int64_t>(mesh.face(f).size()) * (mesh.face_plane_triangle(f) >= 0 ? 1 : 3);
    k.face_points += points;
    k.exact += double(points) * m.exact_face_point;
  }
  return k;
}

namespace {

/// The path the costs choose for sphere p, counted; ties go to exact (the more accurate).
/// A non-spherical particle takes pmm. pmm(q, k) and exact(q, k) run the path on q, with
/// what the model found (k; null for a non-spherical particle).
template <class MeshContext, class Pmm, class Exact>
void take_cheapest(const MeshContext& ctx, Scratch& s, const Particle& p, const Pmm& pmm, const Exact& exact) {
  if (p.shaped) {
    ++s.auto_pmm;
    pmm(p, nullptr);
    return;
  }
  const PathCosts k = path_costs(ctx, s, p);
  if (k.fast) {  // exact's (and pmm's) fast path: the whole volume to the one cell
    ++s.auto_fast;
    ++s.fast_path;
    s.add(k.fast_cell, p.volume);
  } else if (k.pmm < k.exact) {
    ++s.auto_pmm;
    Particle q = p;
    q.shape_template = k.pmm_template;  // the same template the bank gives it, not looked up again
    pmm(q, &k);
  } else {
    ++s.auto_exact;
    exact(p, &k);
  }
}

/// A path that needs nothing of the model's findings, as take_cheapest calls it.
template <class MeshContext>
auto plain(const MeshContext& ctx, Scratch& s, void (*path)(const MeshContext&, Scratch&, const Particle&)) {
  return [&ctx, &s, path](const Particle& q, const PathCosts*) { path(ctx, s, q); };
}

}  // namespace

void grid_pmm(const Context& ctx, Scratch& s, const Particle& p) {
  if (!p.shaped && pmm_sphere_quick(ctx, s, p, [&](std::int64_t cell, double v) { s.deposits.push_back({cell, v}); }))
    return;
  pmm_particle(ctx, s, p);
}

void auto_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const auto add = [&](std::int64_t cell, double v) { s.deposits.push_back({cell, v}); };
  if (!p.shaped && auto_sphere_quick(PmmQuick(ctx), s, p, add)) return;
  take_cheapest(ctx, s, p, plain(ctx, s, grid_pmm), plain(ctx, s, exact_particle));
}
void rectilinear_auto(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  // exact takes the box of cells the model located.
  const auto exact = [&](const Particle& q, const PathCosts* k) {
    k ? rectilinear_exact_in_box(ctx, s, q, k->box) : rectilinear_exact(ctx, s, q);
  };
  take_cheapest(ctx, s, p, plain(ctx, s, rectilinear_pmm), exact);
}
void polymesh_auto(const PolyContext& ctx, Scratch& s, const Particle& p) {
  // The centre's cell, located once by the model.
  const auto pmm = [&](const Particle& q, const PathCosts* k) {
    k ? polymesh_pmm_at(ctx, s, q, k->centre_cell) : polymesh_pmm(ctx, s, q);
  };
  const auto exact = [&](const Particle& q, const PathCosts* k) {
    polymesh_exact_at(ctx, s, q, k->centre_cell, k->walked);
  };
  take_cheapest(ctx, s, p, pmm, exact);
}

}  // namespace vfe::detail

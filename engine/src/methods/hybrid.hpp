// method=auto: per sphere, the cheapest of the fast path, pmm at particle_grid=auto's size
// and the exact overlap, by a cost model of each path on the mesh kind at hand. Exact is at
// least as accurate and as stable as pmm, so the cheaper of the two never falls below pmm
// auto's accuracy; each particle's deposits are those of the path it takes.
#pragma once

#include "methods/exact.hpp"
#include "methods/polymesh.hpp"
#include "methods/rectilinear.hpp"

namespace vfe::detail {

/// A path's estimated cost of one particle, in nanoseconds of one thread: a fixed part per
/// particle and a part per unit of work (pmm: sub-elements; exact: the cells it overlaps).
/// Fixed constants, measured by `vfe_bench_auto_costs` (docs/performance.md, "method=auto"):
/// a cost measured at run time would let the same input take different paths, and so give
/// different fields, from one run or machine to the next.
struct GridCosts {
  double pmm_particle;   ///< rotation, window, emit
  double pmm_point;      ///< one sub-element located in a window
  double pmm_counted;    ///< one sub-element counted per octant (a window of <= 2 x 2 x 2 mesh cells)
  double exact_particle;
  double exact_cell;     ///< one cell of the sphere's box of cells (closed-form sphere-box overlap)
  /// exact on a ball within at most 2 x 2 x 2 cells of a Cartesian grid: all its parts from
  /// one closed-form call (methods/exact.hpp); unused on a rectilinear grid
  double exact_octant_particle;
  double exact_octant_cell;
};
struct PolyCosts {
  double pmm_particle;    ///< locate, rotation
  double pmm_point;       ///< one sub-element located among the candidate cells
  double pmm_candidate;   ///< one cell near the particle (its bounds, faces, bins)
  double exact_particle;  ///< locate, candidates
  double exact_candidate; ///< one candidate cell tested against the ball
  double exact_box_cell;  ///< one cut cell that is an axis-aligned box (closed form)
  double exact_face_point;///< one point of a face of a cut cell that is not a box (polyhedron overlap)
};

/// The constants of each mesh kind (hybrid.cpp).
const GridCosts& cartesian_costs();
const GridCosts& rectilinear_costs();
const PolyCosts& polyhedral_costs();

/// What the model sees of sphere p: the estimated cost of each path (ns); which path the
/// hybrid takes. fast: the ball lies wholly in one cell (one deposit, both paths agree).
struct PathCosts {
  bool fast = false;
  std::int64_t fast_cell = -1;  ///< the cell holding the ball when fast
  /// pmm's template for the sphere (the bank's pick, made once: pmm then takes it as given)
  const kernels::ParticleTemplate* pmm_template = nullptr;
  double pmm = 0, exact = 0;
  std::int64_t pmm_points = 0;  ///< the sub-elements pmm's estimate counts (0 on its own fast path)
  bool counted = false;         ///< pmm would count per octant
  std::int64_t exact_cells = 0; ///< exact's cells (polyMesh: the candidates, also pmm's)
  bool exact_octants = false;   ///< Cartesian grid: the ball spans at most two cells per axis (exact's octant call)
  std::int64_t box_cells = 0, face_points = 0;  ///< polyMesh: exact's cut box cells, cut cells' face points
  std::int64_t centre_cell = -1;  ///< polyMesh: the cell holding the centre (-1: outside the mesh)
  /// polyMesh: when exact's walk found every cell of the ball, the particle number it gave
  /// (s.candidate_cells hold its cells until the next walk or search), else 0
  std::uint64_t walked = 0;
  BallBox box{};  ///< rectilinear grid: the ball's box of cells (exact takes it)
};
PathCosts path_costs(const Context& ctx, Scratch& s, const Particle& p);
PathCosts path_costs(const RectilinearContext& ctx, Scratch& s, const Particle& p);
/// On a polyMesh the exact cost is summed over the candidate cells until it passes pmm's
/// (unless `full`, for calibration), so a sphere that goes to pmm pays little for the choice.
PathCosts path_costs(const PolyContext& ctx, Scratch& s, const Particle& p, bool full = false);

/// pmm as auto runs it on a Cartesian grid: its quick cases (the fast path, the octant count;
/// pmm_sphere_quick, as method=pmm's fused pass) where they apply, else pmm_particle.
void grid_pmm(const Context& ctx, Scratch& s, const Particle& p);

/// The model's cost of pmm's octant count of template t (a window of <= 2 x 2 x 2 cells).
inline double pmm_counted_cost(const kernels::ParticleTemplate& t) {
  const GridCosts& m = cartesian_costs();
  return m.pmm_particle + m.pmm_counted * double(t.size());
}

/// Whether counting pmm's sub-elements of template t per octant costs less than exact on
/// any window the count could take instead (two cells or more; a window of more than two
/// cells per axis costs exact more still): auto_sphere_quick then leaves every sphere to
/// pmm's quick case, and a pass may run pmm's quick cases by chunks (PmmQuick::finish_chunk)
/// and count each sphere they take with auto_count_quick.
inline bool auto_counts_every_window(const kernels::ParticleTemplate& t) {
  const GridCosts& m = cartesian_costs();
  return pmm_counted_cost(t) < m.exact_octant_particle + 2 * m.exact_octant_cell;
}

/// Counts a sphere that pmm's quick case took for auto into auto_fast or auto_pmm: its fast
/// path (the template in one cell) is auto's when the ball itself lies in the cell, else (or
/// for a count) the sphere took pmm. p is read only for a fast path, so a caller may leave
/// it unset for a count.
inline void auto_count_quick(const CartesianGrid& grid, const Particle& p, bool fast_path, std::int64_t& auto_fast,
                             std::int64_t& auto_pmm) {
  std::int64_t lo[3], hi[3];
  ++(fast_path && exact_quick_window(grid, p, lo, hi) && lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]
         ? auto_fast
         : auto_pmm);
}

/// auto's quick case for a sphere on a Cartesian grid, the choice the full model
/// (path_costs) makes, at a fraction of its cost. When counting pmm's sub-elements per
/// octant costs less than exact on two cells, pmm's quick case (fast path or count) takes
/// every sphere it can. Otherwise, for a ball within at most 2 x 2 x 2 cells: the fast path
/// when it lies in one cell; pmm's quick case when counting costs less than exact on the
/// ball's cells; else exact's closed-form parts of the window. False, with nothing added or
/// counted, for any other sphere, and where the full model could choose otherwise (pmm's
/// template in one cell while the ball is not: its estimate is then 0).
template <class Sink>
[[gnu::always_inline]] inline bool auto_sphere_quick(const PmmQuick& quick, Scratch& s, const Particle& p, Sink&& sink,
                       PmmQuick::EmptyOctants empty = PmmQuick::EmptyOctants::skip) {
  const Context& ctx = quick.context();
  const CartesianGrid& grid = ctx.grid;
  const GridCosts& m = cartesian_costs();
  const kernels::ParticleTemplate& t = quick.template_of(p, s);
  const double counted = pmm_counted_cost(t);
  if (auto_counts_every_window(t)) {
    // exact's window is not needed: pmm's quick case decides.
    const std::int64_t fast = s.fast_path;
    if (!quick(s, p, sink, empty)) return false;
    auto_count_quick(grid, p, s.fast_path != fast, s.auto_fast, s.auto_pmm);
    return true;
  }
  std::int64_t lo[3], hi[3];
  if (!ctx.opts.fast_path || !exact_quick_window(grid, p, lo, hi)) return false;
  const int split = int(hi[0] - lo[0]) + int(hi[1] - lo[1]) + int(hi[2] - lo[2]);
  if (split == 0) {  // every path's fast path
    ++s.auto_fast;
    ++s.fast_path;
    sink(grid.index(lo[0], lo[1], lo[2]), p.volume);
    return true;
  }
  if (counted < m.exact_octant_particle + double(1 << split) * m.exact_octant_cell) {
    if (!quick(s, p, sink, empty)) return false;
    ++s.auto_pmm;
    return true;
  }
  const double half = p.radius * t.reach;
  bool template_in_one_cell = true;
  for (int d = 0; d < 3; ++d)
    template_in_one_cell &= hi[d] == lo[d] || CartesianGrid::fast_floor(grid.axis_coordinate(d, p.centre[d] - half)) ==
                                                   CartesianGrid::fast_floor(grid.axis_coordinate(d, p.centre[d] + half));
  if (template_in_one_cell) return false;
  ++s.auto_exact;
  exact_window_deposit(grid, s, p, lo, hi, sink);
  return true;
}

// method=auto's drivers: a non-spherical particle takes pmm.
void auto_particle(const Context& ctx, Scratch& s, const Particle& p);
void rectilinear_auto(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void polymesh_auto(const PolyContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

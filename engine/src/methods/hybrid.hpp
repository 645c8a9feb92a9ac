// method=auto: per sphere, the cheapest of the fast path, pmm at particle_grid=auto's size
// and the exact overlap, by a cost model of each path on the mesh kind at hand. Exact is at
// least as accurate and as stable as pmm, so the cheaper of the two never falls below pmm
// auto's accuracy; each particle's deposits are those of the path it takes.
#pragma once

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
  std::int64_t box_cells = 0, face_points = 0;  ///< polyMesh: exact's cut box cells, cut cells' face points
};
PathCosts path_costs(const Context& ctx, Scratch& s, const Particle& p);
PathCosts path_costs(const RectilinearContext& ctx, Scratch& s, const Particle& p);
/// On a polyMesh the exact cost is summed over the candidate cells until it passes pmm's
/// (unless `full`, for calibration), so a sphere that goes to pmm pays little for the choice.
PathCosts path_costs(const PolyContext& ctx, Scratch& s, const Particle& p, bool full = false);

/// pmm as auto runs it on a Cartesian grid: its quick cases (the fast path, the octant count;
/// pmm_sphere_quick, as method=pmm's fused pass) where they apply, else pmm_particle.
void grid_pmm(const Context& ctx, Scratch& s, const Particle& p);

/// auto's quick case for a sphere on a Cartesian grid, the choice the full model would make
/// at a fraction of its cost: when counting pmm's sub-elements per octant costs less than
/// exact on the fewest cells it can take (two), a sphere whose template lies in at most
/// 2 x 2 x 2 mesh cells goes to PmmQuick (the fast path or the count). False, with
/// nothing added or counted, otherwise.
template <class Sink>
bool auto_sphere_quick(const PmmQuick& quick, Scratch& s, const Particle& p, Sink&& sink) {
  const Context& ctx = quick.context();
  const GridCosts& m = cartesian_costs();
  Particle q = p;
  q.shape_template = &ctx.template_for(p);  // looked up once
  if (!(m.pmm_particle + m.pmm_counted * double(q.shape_template->size()) < m.exact_particle + 2 * m.exact_cell))
    return false;
  const std::int64_t fast = s.fast_path;
  if (!quick(s, q, sink)) return false;
  // One deposit is the fast path when the ball itself lies in the cell (exact's as well).
  ++(s.fast_path != fast && single_cell(ctx, p.centre, Eigen::Vector3d::Constant(p.radius)) >= 0 ? s.auto_fast
                                                                                                  : s.auto_pmm);
  return true;
}

// method=auto's drivers: a non-spherical particle takes pmm.
void auto_particle(const Context& ctx, Scratch& s, const Particle& p);
void rectilinear_auto(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void polymesh_auto(const PolyContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

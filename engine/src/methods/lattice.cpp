#include "methods/lattice.hpp"

#include "methods/hybrid.hpp"

#include <algorithm>
#include <cmath>

namespace vfe::detail {

double lattice_reach(const Options& opts) {
  // direct deposits at the centre; sphere templates and divided's points lie within the
  // ball; gaussian's kernel is cut at 3 sigma (sigma in diameters), porous_cube's cube has
  // side gamma diameters.
  switch (opts.method) {
    case Method::direct: return 0.0;
    case Method::gaussian: return std::max(1.0, 6.0 * opts.sigma);
    case Method::porous_cube: return std::max(1.0, opts.gamma);
    default: return 1.0;
  }
}

Eigen::AlignedBox3d lattice_footprint_bounds(Method m, const BoxLattice& lattice) {
  // Clear of the boundary by a few node tolerances, so that neither mesh sees an outside.
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(4 * lattice.tolerance);
  Eigen::AlignedBox3d box(lattice.bounds.min() + margin, lattice.bounds.max() - margin);
  if (m != Method::big_particle) return box;
  // big_particle tests cell centres: the grids' virtual cells beyond a side continue with the
  // end cell's size, so a ball short of the first virtual centre, half an end cell beyond
  // the side, holds real centres only (the polyMesh's candidates).
  for (int d = 0; d < 3; ++d) {
    double h_lo, h_hi;
    if (lattice.cartesian) {
      h_lo = h_hi = lattice.cartesian->spacing()[d];
    } else {
      const std::vector<double>& x = lattice.rectilinear->nodes(d);
      h_lo = x[1] - x[0];
      h_hi = x[x.size() - 1] - x[x.size() - 2];
    }
    box.min()[d] -= 0.5 * h_lo - 8 * lattice.tolerance;
    box.max()[d] += 0.5 * h_hi - 8 * lattice.tolerance;
  }
  return box;
}

LatticeBoundary lattice_boundary(Method m, const BoxLattice& lattice) {
  switch (m) {
    // Volume beyond the mesh goes, point by point, to the cell whose centre is nearest: on
    // evenly spaced nodes that is the clamped cell the Cartesian grid gives (a graded axis
    // may have a nearer centre in a neighbouring cell).
    case Method::direct:
    case Method::pmm:
    case Method::divided: return lattice.cartesian ? LatticeBoundary::grid : LatticeBoundary::polymesh;
    // The polyMesh's drivers give what the cells do not hold, as one volume, to the cell
    // nearest to the centre: so does the Cartesian grid's exact, while the separable
    // kernels give each cell beyond a side to the cell along it.
    case Method::exact: return lattice.cartesian ? LatticeBoundary::grid : LatticeBoundary::rest;
    // auto takes pmm or exact per particle: the rule both share on evenly spaced nodes, each
    // path's own on graded ones.
    case Method::automatic: return lattice.cartesian ? LatticeBoundary::grid : LatticeBoundary::per_path;
    case Method::gaussian:
    case Method::porous_cube: return LatticeBoundary::rest;
    // big_particle shares among the centres of real cells only.
    default: return LatticeBoundary::polymesh;
  }
}

LatticeContext lattice_context(const PolyContext& poly, const Context* cartesian,
                               const RectilinearContext* rectilinear, const BoxLattice& lattice) {
  const MethodDrivers& drivers = method_drivers(poly.opts.method);
  return LatticeContext{poly,
                        drivers.polyhedral,
                        cartesian,
                        drivers.cartesian,
                        rectilinear,
                        drivers.rectilinear,
                        lattice,
                        lattice_reach(poly.opts),
                        lattice_footprint_bounds(poly.opts.method, lattice),
                        lattice_boundary(poly.opts.method, lattice)};
}

namespace {

/// Lattice index of the cell whose centre is nearest to x (as KdTreeLocator::nearest_cell,
/// but for ties). Distances separate by axis, so per axis: on evenly spaced nodes the
/// clamped cell; on graded ones the nearest of that cell's and its neighbours' centres.
std::int64_t nearest_centre(const BoxLattice& lattice, const Eigen::Vector3d& x) {
  if (lattice.cartesian) return lattice.cartesian->nearest(x);
  const RectilinearGrid& grid = *lattice.rectilinear;
  std::int64_t at[3];
  for (int d = 0; d < 3; ++d) {
    const std::vector<double>& nodes = grid.nodes(d);
    const std::int64_t n = grid.cells()[d];
    const std::int64_t i = std::clamp<std::int64_t>(grid.axis_index(d, x[d]), 0, n - 1);
    const auto distance = [&](std::int64_t k) {
      return std::abs(x[d] - 0.5 * (nodes[static_cast<std::size_t>(k)] + nodes[static_cast<std::size_t>(k + 1)]));
    };
    at[d] = i;
    for (const std::int64_t k : {i - 1, i + 1})
      if (k >= 0 && k < n && distance(k) < distance(at[d])) at[d] = k;
  }
  return grid.index(at[0], at[1], at[2]);
}

std::int64_t locate(const BoxLattice& lattice, const Eigen::Vector3d& x) {
  return lattice.cartesian ? lattice.cartesian->locate(x) : lattice.rectilinear->locate(x);
}

void grid_driver(const LatticeContext& ctx, Scratch& s, const Particle& p) {
  if (ctx.cartesian)
    ctx.cartesian_driver(*ctx.cartesian, s, p);
  else
    ctx.rectilinear_driver(*ctx.rectilinear, s, p);
  const std::int64_t* map = ctx.lattice.cell_map.data();  // the dropped slot maps to itself
  for (Deposit& d : s.deposits) d.cell = map[d.cell];
  ++s.lattice_particles;
}

}  // namespace

void lattice_particle(const LatticeContext& ctx, Scratch& s, const Particle& p) {
  if (p.shaped) {  // a body's footprint is not the ball's
    ctx.poly_driver(ctx.poly, s, p);
    return;
  }
  const double half = ctx.reach * p.radius;
  const Eigen::AlignedBox3d& box = ctx.footprint_bounds;
  const Eigen::AlignedBox3d& lattice = ctx.lattice.bounds;
  const bool inside = (p.centre.array() - half > box.min().array()).all() &&
                      (p.centre.array() + half < box.max().array()).all() &&
                      (p.centre.array() > lattice.min().array()).all() && (p.centre.array() < lattice.max().array()).all();
  if (inside || ctx.boundary == LatticeBoundary::grid) {
    grid_driver(ctx, s, p);
    return;
  }
  if (ctx.boundary == LatticeBoundary::polymesh) {
    ctx.poly_driver(ctx.poly, s, p);
    return;
  }
  if (ctx.boundary == LatticeBoundary::per_path) {
    // The grid's choice (rectilinear_auto, below, makes the same one from the same costs).
    const PathCosts k = path_costs(*ctx.rectilinear, s, p);
    if (!k.fast && k.pmm < k.exact) {
      ++s.auto_pmm;
      Particle q = p;
      q.shape_template = k.pmm_template;
      polymesh_pmm(ctx.poly, s, q);
      return;
    }
  }
  // LatticeBoundary::rest (and per_path's exact): the grid's cells, then what they miss by
  // the polyMesh's rule.
  Particle dropping = p;
  dropping.outside = Outside::drop;
  const std::int64_t outside_before = s.outside_particles;
  grid_driver(ctx, s, dropping);
  s.outside_particles = outside_before;
  const std::int64_t dropped_slot = ctx.poly.locator->mesh().cell_count();
  double rest = 0;
  std::erase_if(s.deposits, [&](const Deposit& d) {
    if (d.cell != dropped_slot) return false;
    rest += d.volume;
    return true;
  });
  if (!(rest > 1e-12 * p.volume)) return;  // round-off, as the polyMesh's drivers take it
  // outside_poly's cells, from the lattice instead of the polyMesh's locators.
  const std::int64_t* map = ctx.lattice.cell_map.data();
  const auto nearest = [&] { return map[nearest_centre(ctx.lattice, p.centre)]; };
  bool flagged = false;
  apply_outside(s, p, rest, p.outside, dropped_slot, flagged, nearest, [&] {
    const std::int64_t cell = locate(ctx.lattice, p.centre);
    return cell >= 0 ? map[cell] : nearest();
  });
}

}  // namespace vfe::detail

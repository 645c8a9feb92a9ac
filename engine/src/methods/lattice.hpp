// Every method on a polyMesh whose cells are a lattice of axis-aligned boxes (BoxLattice):
// the grid of the same cells computes each particle and its deposits are renumbered into
// the polyMesh's cells. Where the particle reaches the boundary, the polyMesh's outside
// policy must hold (docs/polymesh.md): the grid's driver serves as is where its outside
// rule is the polyMesh's, serves with its outside volume handed to the polyMesh's rule
// where that rule takes the volume as a whole, and the polyMesh's driver serves otherwise.
// On a Cartesian lattice whose rule is the grid's (LatticeBoundary::grid), direct, pmm and
// exact skip this wrapper: the engine runs the grid's fused passes over all particles and
// renumbers each deposit (fused_grid in engine.cpp); this file serves the rest.
#pragma once

#include "box_lattice.hpp"
#include "methods/registry.hpp"

namespace vfe::detail {

/// How a particle that reaches beyond the lattice's box is computed.
enum class LatticeBoundary {
  grid,      ///< the grid's driver: its rule is the polyMesh's (nearest cell = clamped cell)
  rest,      ///< the grid's driver with outside=drop; the dropped volume goes to outside_poly at the centre
  polymesh,  ///< the polyMesh's driver
  /// method=auto on a graded lattice: the path the grid's cost model picks, then that path's
  /// rule (exact: rest; pmm: the polyMesh's driver)
  per_path,
};

struct LatticeContext {
  const PolyContext& poly;
  DriverFn<PolyContext> poly_driver;
  const Context* cartesian;  ///< one of cartesian and rectilinear is set
  DriverFn<Context> cartesian_driver;
  const RectilinearContext* rectilinear;
  DriverFn<RectilinearContext> rectilinear_driver;
  const BoxLattice& lattice;
  /// Half the side of the cube about a sphere's centre that holds what the method
  /// deposits, in radii (lattice_reach).
  double reach;
  /// Where that cube must lie, with the centre inside the lattice's box, for both meshes
  /// to see nothing beyond it (lattice_footprint_bounds).
  Eigen::AlignedBox3d footprint_bounds;
  LatticeBoundary boundary;
};

double lattice_reach(const Options& opts);
Eigen::AlignedBox3d lattice_footprint_bounds(Method m, const BoxLattice& lattice);
LatticeBoundary lattice_boundary(Method m, const BoxLattice& lattice);

/// The lattice context of one compute.
LatticeContext lattice_context(const PolyContext& poly, const Context* cartesian,
                               const RectilinearContext* rectilinear, const BoxLattice& lattice);

void lattice_particle(const LatticeContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

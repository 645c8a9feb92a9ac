// The drivers of direct, pmm and exact on an OpenFOAM polyMesh.
#pragma once

#include "methods/driver.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"

namespace vfe::detail {

struct PolyContext {
  const CellLocator* locator;
  const Options& opts;
};

/// True when the ball (c, r) lies inside cell `cell`: deeper than r plus the warp below
/// every face plane. Sufficient for the fast path (a cell that is not convex answers no).
bool ball_inside_cell(const PolyMesh& mesh, std::int64_t cell, const Eigen::Vector3d& c, double r);

/// Volume of particle p that lies outside the mesh, handled by the outside policy:
/// `nearest` gives it to the cell with the centre nearest to `at`, `centre` to centre_cell
/// (or the cell nearest to p's centre when that is -1); flagged counts the particle once.
void outside_poly(const PolyContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
                  std::int64_t centre_cell, bool& flagged);

/// One particle on a polyMesh: pmm deposits template t (unit-sphere or shape template,
/// scaled by p.radius and rotated); with t null (direct) everything goes to the cell
/// holding the body's centroid (zero for spheres). Outside points follow the policy,
/// `nearest` meaning the cell with the nearest centre. Every sub-element lands where
/// CellLocator::locate_from (and nearest_cell) would put it, found per particle from the
/// cells near it (docs/polymesh.md, "How pmm locates sub-elements on a polyMesh").
void polymesh_particle(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate* t,
                       const Eigen::Vector3d& centroid);

/// exact on a polyMesh: the exact overlap volume of sphere p with every cell it reaches,
/// each cell bounded by its faces: a planar face as its polygon, a warped one as the fan
/// of triangles (face apex, two consecutive points), the surface of the point-in-cell
/// test; what lies beyond the mesh follows the outside policy.
void polymesh_exact_particle(const PolyContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

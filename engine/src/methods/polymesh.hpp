// The drivers of direct and pmm on an OpenFOAM polyMesh.
#pragma once

#include "methods/driver.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"

namespace vfe::detail {

struct PolyContext {
  const CellLocator* locator;
  const Options& opts;
};

/// One particle on a polyMesh: pmm deposits template t (unit-sphere or shape template,
/// scaled by p.radius and rotated); with t null (direct) everything goes to the cell
/// holding the body's centroid (zero for spheres). Outside points follow the policy,
/// `nearest` meaning the cell with the nearest centre.
void polymesh_particle(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate* t,
                       const Eigen::Vector3d& centroid);

/// exact on a polyMesh: the exact overlap volume of sphere p with every cell it reaches
/// (each cell bounded by its faces split into triangles at the face centres, as the
/// point-in-cell test and OpenFOAM's geometry do); what lies beyond the mesh follows the
/// outside policy.
void polymesh_exact_particle(const PolyContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

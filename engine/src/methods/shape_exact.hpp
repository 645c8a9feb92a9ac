// exact for non-spherical particles: ellipsoids and closed triangle meshes placed by the
// particle's centre, scale and rotation, overlapped exactly with every cell they reach
// (kernels/ellipsoid_overlap.hpp, kernels/mesh_overlap.hpp). Spheres keep their drivers.
#pragma once

#include "methods/polymesh.hpp"
#include "methods/rectilinear.hpp"

#include <vfe/kernels/shape.hpp>

#include <string>

namespace vfe::detail {

/// "" when method=exact computes this shape exactly (sphere, ellipsoid, mesh), otherwise
/// why not and what to use instead (superquadrics and clumps have no exact overlap here).
std::string exact_shape_refusal(const kernels::Shape& shape, std::int32_t id);

// The exact drivers for any particle: a shaped one by its body's exact overlaps, a sphere
// by the sphere drivers (exact_particle, rectilinear_exact, polymesh_exact).
void exact_any_particle(const Context& ctx, Scratch& s, const Particle& p);
void rectilinear_exact_any(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void polymesh_exact_any(const PolyContext& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail

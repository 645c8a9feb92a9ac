// Exact volume of a polyhedral particle (a closed triangle mesh, placed by a linear map
// and a translation) inside a cell. The particle is the signed union of the tetrahedra
// (o, a, b, c) from a reference point o to its triangles, so non-convex particles work;
// each tetrahedron is clipped by the cell (r3d-style plane clipping, polytope.hpp).
#pragma once

#include <vfe/kernels/polytope.hpp>
#include <vfe/kernels/shape.hpp>

#include <Eigen/Core>

#include <span>

namespace vfe::kernels {

/// A triangle mesh in template units placed in space: x = translation + linear * p (for
/// a particle, linear = rotation * scale; a reflection gives the same volumes).
struct PlacedMesh {
  const TriangleMesh* mesh = nullptr;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();
};

/// Volume of the placed mesh inside the convex region {x : n_k . x <= d_k} (planes as
/// (n, d) 4-vectors, at most ~50). Exact to round-off. Allocation-free.
double mesh_halfspaces_overlap(const PlacedMesh& m, std::span<const Eigen::Vector4d> planes);

/// Volume of the placed mesh inside the box [lo, hi]: tetrahedra whose bounding box
/// misses the box are skipped, those inside it counted whole. Allocation-free.
double mesh_box_overlap(const PlacedMesh& m, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Volume of the placed mesh inside a cell given as signed tetrahedra (TetrahedraView):
/// every pair of particle and cell tetrahedra whose boxes meet is clipped (the particle
/// tetrahedron by the cell tetrahedron's 4 planes). Allocation-free.
double mesh_polyhedron_overlap(const PlacedMesh& m, TetrahedraView cell_tets);

/// The same for a cell given by its faces (for_each_face_tetrahedron's layout).
double mesh_polyhedron_overlap(const PlacedMesh& m, std::span<const Eigen::Vector3d> vertices,
                               std::span<const std::int32_t> face_offsets,
                               std::span<const std::int32_t> face_vertices);

}  // namespace vfe::kernels

// Exact overlap volume of an ellipsoid with a polyhedral cell or a box. The affine map
// y = D^-1 R^T (x - centre) turns the ellipsoid into the unit ball and each cell into a
// polyhedron (a box into a parallelepiped) with the same faces, so the exact
// sphere-polyhedron overlap gives the volume times the map's determinant a b c.
#pragma once

#include <vfe/kernels/polytope.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <span>

namespace vfe::kernels {

/// The ellipsoid {centre + R diag(semi_axes) y : |y| <= 1}: its axes are the columns of
/// `rotation` (a reflection is accepted: the ellipsoid is symmetric about its centre).
struct Ellipsoid {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Ones();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();

  double volume() const;
  /// The map to the unit ball's frame, y = to_unit * (x - centre).
  Eigen::Matrix3d to_unit() const;
};

/// Volume of the ellipsoid inside the polyhedron given by its planar faces (the layout
/// and orientation of sphere_polyhedron_overlap; a cell with warped faces: the
/// tetrahedra form below). `scratch` must hold vertices.size() points
/// (the mapped vertices; caller-owned so the call does not allocate). Exact to round-off
/// (a few 1e-16 of the ellipsoid's volume) with the guarantees of sphere_polyhedron_overlap:
/// exactly 0 for a cell the ellipsoid misses, exactly its volume for a cell containing it.
double ellipsoid_polyhedron_overlap(const Ellipsoid& e, std::span<const Eigen::Vector3d> vertices,
                                    std::span<const std::int32_t> face_offsets,
                                    std::span<const std::int32_t> face_vertices, std::span<Eigen::Vector3d> scratch);

/// Volume of the ellipsoid inside the box [lo, hi] (0 for an empty box). Allocation-free.
double ellipsoid_box_overlap(const Ellipsoid& e, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Volume of the ellipsoid inside the tetrahedron (a, b, c, d), signed by its orientation
/// (as tetrahedron_box_overlap), so a cell given as signed tetrahedra is their sum.
double ellipsoid_tetrahedron_overlap(const Ellipsoid& e, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                     const Eigen::Vector3d& c, const Eigen::Vector3d& d);

/// Volume of the ellipsoid inside a cell given as signed tetrahedra (TetrahedraView).
double ellipsoid_polyhedron_overlap(const Ellipsoid& e, TetrahedraView tets);

}  // namespace vfe::kernels

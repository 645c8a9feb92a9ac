// Exact overlap volume of a sphere with a polyhedron given by its boundary faces.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <span>

namespace vfe::kernels {

/// Volume of the ball |x - centre| <= radius intersected with the polyhedron bounded by
/// `face_offsets.size() - 1` planar polygon faces: face f has the vertices
/// vertices[face_vertices[k]] for k in [face_offsets[f], face_offsets[f + 1]), ordered
/// counter-clockwise seen from outside (outward right-hand normal). Faces may be
/// non-convex polygons; the polyhedron may be non-convex (any closed, consistently
/// oriented surface: the result is the integral of its winding number over the ball).
/// Closed form (no quadrature), absolute error a few 1e-16 of the ball volume:
///  - exactly 0 when the ball misses the vertices' bounding box, or when no face reaches
///    into the open ball and the centre is outside;
///  - exactly the ball volume when no face reaches into the open ball and the centre is
///    inside;
///  - the polyhedron's volume (divergence theorem) when every vertex is in the ball;
///  - otherwise clamped to [0, min(ball volume, polyhedron volume)] (round-off only).
/// 0 for radius <= 0; faces of zero area and edges of zero length contribute nothing.
/// Allocation-free.
double sphere_polyhedron_overlap(const Eigen::Vector3d& centre, double radius,
                                 std::span<const Eigen::Vector3d> vertices,
                                 std::span<const std::int32_t> face_offsets,
                                 std::span<const std::int32_t> face_vertices);

/// The same for a centre already located: `centre_inside` says whether the centre lies
/// inside the closed surface (winding number 1) or not (0), as exact point location on
/// the same faces tells it. The faces given may then be any part of the surface that holds
/// every face reaching into the open ball; the others add nothing and need not be given
/// (the vertices need only be those of the faces given). The result is the overlap to the
/// general function's round-off, clamped to [0, ball volume] (clamp it to the polyhedron's
/// volume, which this part of the surface cannot give, if needed). No value when the centre
/// lies within rounding (about 1e-12 of the largest coordinate) of the plane of a face that
/// reaches into the ball, or close to such a face's edge line: there the winding number
/// jumps, so call the general function with the whole surface. (No NaN: hosts such as
/// OpenFOAM trap the invalid operation a comparison with NaN raises.) A wrong
/// `centre_inside` gives a wrong volume.
/// Cost: a face that does not reach into the ball costs its plane only, and the rest need
/// fewer arc tangents than in the general function.
std::optional<double> sphere_polyhedron_overlap_located(const Eigen::Vector3d& centre, double radius,
                                                        bool centre_inside,
                                                        std::span<const Eigen::Vector3d> vertices,
                                                        std::span<const std::int32_t> face_offsets,
                                                        std::span<const std::int32_t> face_vertices);

/// The located sum face by face, for meshes whose cells share faces: one planar face's
/// term (its vertices in order, right-hand normal pointing out of the cell it serves),
/// 0 for a face that does not reach into the open ball. A cell's overlap is
/// sphere_located_overlap of the sum of the terms of its faces (every face that reaches
/// into the ball), the same as sphere_polyhedron_overlap_located's to round-off; the cell
/// on the face's other side takes the term negated, so a face shared by two cut cells is
/// computed once. No value where sphere_polyhedron_overlap_located gives none (the centre
/// within rounding of the face's plane, or near one of its reaching edges' lines).
std::optional<double> sphere_face_located_term(const Eigen::Vector3d& centre, double radius,
                                               std::span<const Eigen::Vector3d> polygon);

/// The sum of sphere_face_located_term over the fan of triangles (apex, rim[i], rim[i+1])
/// (rim closed: the last point's next is the first), a warped face's surface; no value
/// where a triangle's term has none. The same to round-off, for less work: the spokes,
/// shared by two triangles, are measured once, and a fan whose box misses the ball costs
/// that test only.
std::optional<double> sphere_fan_located_term(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& apex,
                                              std::span<const Eigen::Vector3d> rim);

/// A located cell's overlap from the sum of its reaching faces' terms: the ball's volume
/// if the centre is inside, plus the sum, clamped to [0, ball volume].
double sphere_located_overlap(double radius, bool centre_inside, double face_terms);

/// Volume of the ball intersected with the tetrahedron (a, b, c, d), either orientation;
/// 0 for a flat tetrahedron.
double sphere_tetrahedron_overlap(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d);

}  // namespace vfe::kernels

// Exact overlap volume of a sphere with a polyhedron given by its boundary faces.
//
// Cone decomposition from the ball's centre c. For a closed, outward-oriented surface the
// indicator of the polyhedron is, almost everywhere, the signed sum over its faces F of
// the indicators of the pyramids (c, F), the sign being that of h_F = n_F . (x_F - c), the
// height of F's plane above c along its outward normal (faces through c add nothing).
// So
//
//     |B n P| = sum_F sign(h_F) |B n pyramid(c, F)|.
//
// In spherical coordinates about c, a direction that meets F's plane at distance
// rho <= R (inside the disc of radius a = sqrt(R^2 - h^2) about the foot p of c)
// contributes the pyramid's part, elsewhere the ball's, so with h = |h_F|
//
//     |B n pyramid(c, F)| = h/3 |F n disc| + R^3/3 (Omega(F) - Omega(F n disc)),
//
// Omega being the solid angle seen from c. F splits into the triangles (p, A, B) over its
// edges A -> B, signed by their orientation in the plane, and each of those into two right
// triangles (p, q, q + s t) at the foot q of p on line AB (legs d = |q - p| and s along the
// unit edge direction t; the measure is odd in s). For one right triangle:
//  - its solid angle (Van Oosterom-Strackee, free of cancellation; rho = |q - c|,
//    l = |q + s t - c|):  tan(Omega / 2) = d s / ((rho + h) (l + rho));
//  - the disc misses the edge (a <= d): a sector of angle alpha = atan2(s, d), area
//    alpha a^2 / 2 and solid angle alpha (1 - h / R);
//  - the triangle lies in the disc (l <= R): area d s / 2 and Omega(F n disc) = Omega;
//  - otherwise the circle crosses the edge at s_in = sqrt(a^2 - d^2): the right triangle
//    (d, s_in) plus the sector between its angle and alpha.
// A face that does not reach into the open ball (its plane misses it, or no edge comes
// nearer than R and p lies outside the face) is seen beyond the sphere: its cone adds
// R^3/3 Omega(F), summed over the fan of F about its first vertex with Van
// Oosterom-Strackee's formula for triangles. Every term is bounded by about R^3 and
// computed without cancellation, so the result has an absolute error of a few ulps of the
// ball volume per edge.
//
// With the centre's winding number w known (point location gives it), the solid angles of
// all faces add up to 4 pi w, so
//
//     |B n P| = w |B| + sum over faces F reaching into the ball of
//               sign(h_F) (h/3 |F n disc| - R^3/3 Omega(F n disc)):
//
// faces beyond the sphere cost nothing, and a right triangle needs no Omega of its own. A
// sector of the disc then adds alpha times -(R - h)^2 (2R + h) / 6 (the cap beyond the
// plane, per radian), and an edge whose line the disc misses needs one atan2 for the angle
// it spans. w jumps where a face plane passes through the centre, so a centre within
// rounding of a reaching face's plane takes the general formula.
#include "vfe/kernels/sphere_polyhedron_overlap.hpp"
#include "vfe/kernels/v3_clones.hpp"

#include "ratio_angle.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>

namespace vfe::kernels {
namespace {

using detail::ratio_angle;
using detail::upper_half_angle;

/// With the winding number known, a centre nearer than kEdgeMargin times an edge's length
/// (from the centre's foot) to the line of an edge the disc reaches takes the general
/// formula: the result's error is about 1e-17 of the ball over that distance ratio.
constexpr double kEdgeMargin2 = 1e-2 * 1e-2;

/// Fans of more points than this take their triangles one by one (the shared data lives on
/// the stack).
constexpr std::int32_t kMostFanPoints = 32;

/// What one face plane's edges share.
struct FacePlane {
  double h;    ///< |height| of the plane above the centre, in (0, r)
  double r;    ///< ball radius
  double r3;   ///< r^3
  double a2;   ///< squared radius of the disc the ball cuts from the plane
  double cap;  ///< 1 - h / r: solid angle per radian of a sector of that disc
  double cap_volume;  ///< (r - h)^2 (2 r + h) / 6: volume per radian of the cap beyond the plane
};

/// |B n pyramid(c, right triangle (p, q, q + s t))| with d = |q - p| > 0 and
/// rho = sqrt(h^2 + d^2); odd in s.
double right_triangle_cone(const FacePlane& pl, double d, double rho, double s) {
  const double sa = std::fabs(s);
  if (sa == 0) return 0;
  const double h = pl.h;
  const double ell = std::sqrt(rho * rho + sa * sa);
  const double omega = 2 * ratio_angle(d * sa, (rho + h) * (ell + rho));
  double v;
  if (pl.a2 <= d * d) {
    const double alpha = ratio_angle(sa, d);
    v = h / 6 * alpha * pl.a2 + pl.r3 / 3 * (omega - alpha * pl.cap);
  } else if (ell <= pl.r) {
    v = h * d * sa / 6;
  } else {
    const double s_in = std::sqrt(pl.a2 - d * d);
    const double omega_in = 2 * ratio_angle(d * s_in, (rho + h) * (pl.r + rho));
    // alpha - atan2(s_in, d); sa > s_in here (the ball's edge lies within the segment)
    const double beyond = ratio_angle(d * std::max(sa - s_in, 0.0), d * d + sa * s_in);
    v = h / 6 * (d * s_in + beyond * pl.a2) + pl.r3 / 3 * (omega - omega_in - beyond * pl.cap);
  }
  return s < 0 ? -v : v;
}

/// right_triangle_cone less R^3/3 times the right triangle's solid angle, for a line the
/// disc reaches (a > d); odd in s.
double right_triangle_cone_in_disc(const FacePlane& pl, double d, double rho, double s) {
  const double sa = std::fabs(s);
  if (sa == 0) return 0;
  const double h = pl.h;
  double v;
  if (rho * rho + sa * sa <= pl.r * pl.r) {
    const double ell = std::sqrt(rho * rho + sa * sa);
    v = h * d * sa / 6 - pl.r3 / 3 * 2 * ratio_angle(d * sa, (rho + h) * (ell + rho));
  } else {
    const double s_in = std::sqrt(pl.a2 - d * d);
    const double omega_in = 2 * ratio_angle(d * s_in, (rho + h) * (pl.r + rho));
    const double beyond = ratio_angle(d * std::max(sa - s_in, 0.0), d * d + sa * s_in);
    v = h * d * s_in / 6 - pl.r3 / 3 * omega_in - beyond * pl.cap_volume;
  }
  return s < 0 ? -v : v;
}

/// Signed solid angle of the triangle (a, b, c) (positions relative to the centre) seen
/// from the centre, positive when its right-hand normal points away from it (Van
/// Oosterom-Strackee; the triple product from the edges, for accuracy).
double triangle_solid_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double triple = a.dot((b - a).cross(c - a));
  return 2 * std::atan2(triple, la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la);
}

/// True when the segment a -> b (relative to the centre) comes nearer than r to the centre.
bool segment_in_ball(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r2) {
  const Eigen::Vector3d d = b - a;
  const double dd = d.squaredNorm();
  const double t = dd > 0 ? std::clamp(-a.dot(d) / dd, 0.0, 1.0) : 0.0;
  return (a + t * d).squaredNorm() < r2;
}

}  // namespace

namespace {

/// The ball and the rounding bound the face sums share.
struct Ball {
  double r, r2, r3;
  /// A bound on the rounding of a face plane's height above the centre (relative
  /// coordinates, normal, mean): about 1e4 ulps of the largest coordinate involved.
  double height_rounding;
};

/// The ball (centre, r) where it reaches into the box [lo, hi] of the faces' points, with
/// the rounding bound of their coordinates and the centre's; none where the box misses
/// the open ball (no face in the box reaches into it).
std::optional<Ball> ball_reaching(const Eigen::Vector3d& centre, double r, const Eigen::Vector3d& lo,
                                  const Eigen::Vector3d& hi) {
  const double r2 = r * r;
  if ((centre.cwiseMax(lo).cwiseMin(hi) - centre).squaredNorm() >= r2) return std::nullopt;
  return Ball{r, r2, r2 * r,
              1e-12 * std::max({centre.cwiseAbs().maxCoeff(), lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()})};
}

/// [lo, hi] grown to hold `points`.
void extend_box(std::span<const Eigen::Vector3d> points, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  for (const Eigen::Vector3d& v : points) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
}

/// What one face adds to overlap()'s sums.
struct FaceSums {
  double volume = 0;          ///< the cones' sum (the located sum's terms when the winding is known)
  double polyhedron = 0;      ///< the divergence theorem's sum (winding unknown)
  bool boundary_in_ball = false;  ///< some face reaches into the open ball
  bool unsure = false;        ///< winding known, centre within rounding of a reaching face's plane or edge line
};

/// An edge's unit direction and length (zero direction for a zero length).
struct EdgeDirection {
  Eigen::Vector3d t;
  double length;
};

EdgeDirection edge_direction(const Eigen::Vector3d& edge) {
  const double length = edge.norm();
  return {length > 0 ? Eigen::Vector3d(edge / length) : Eigen::Vector3d::Zero(), length};
}

/// Adds face [begin, end) of vertex(k) (positions relative to the centre) to the sums:
/// with the winding number known (`known`) its term of the located sum, else its cone and
/// its part of the polyhedron's volume. `contained`: every vertex lies in the ball (only
/// the volume is wanted). edge(k): the direction of the edge from vertex k to the next
/// (a fan's triangles share their spokes' directions).
template <class Vertex, class Edge>
void add_face(const Vertex& vertex, const Edge& edge, std::int32_t begin, std::int32_t end, const Ball& ball,
              bool known, bool contained, FaceSums& sums) {
  if (end - begin < 3) return;
  const double r = ball.r, r2 = ball.r2, r3 = ball.r3;
  // Whether the foot of the centre lies inside the face: winding number of the face
  // projected along the normal's largest axis.
  const auto foot_inside = [&](const Eigen::Vector3d& foot, const Eigen::Vector3d& normal) {
    Eigen::Index axis = 0;
    normal.cwiseAbs().maxCoeff(&axis);
    const Eigen::Index i = (axis + 1) % 3, j = (axis + 2) % 3;
    int winding = 0;
    Eigen::Vector3d a = vertex(end - 1) - foot;
    for (std::int32_t k = begin; k < end; ++k) {
      const Eigen::Vector3d b = vertex(k) - foot;
      const double left = a[i] * b[j] - a[j] * b[i];
      if (a[j] <= 0) {
        if (b[j] > 0 && left > 0) ++winding;
      } else if (b[j] <= 0 && left < 0) {
        --winding;
      }
      a = b;
    }
    return winding != 0;
  };
  // Area vector (fan about the first vertex) and the plane's height above the centre.
  const Eigen::Vector3d u0 = vertex(begin);
  Eigen::Vector3d area2 = Eigen::Vector3d::Zero(), sum = u0;
  Eigen::Vector3d prev = vertex(begin + 1);
  sum += prev;
  for (std::int32_t k = begin + 2; k < end; ++k) {
    const Eigen::Vector3d u = vertex(k);
    area2 += (prev - u0).cross(u - u0);
    sum += u;
    prev = u;
  }
  const double norm = area2.norm();
  if (!(norm > 0)) return;
  // moment = height * norm * count: no division until the face is known to reach the
  // ball (most faces of a cut cell lie beyond it).
  const double count = double(end - begin);
  const double moment = area2.dot(sum);
  if (!known) sums.polyhedron += moment / (6 * count);
  if (contained) return;

  // A face that does not reach into the open ball is seen from the centre beyond the
  // sphere: its cone adds R^3/3 times its (signed) solid angle.
  const auto face_solid_angle = [&] {
    double omega = 0;
    for (std::int32_t k = begin + 1; k + 1 < end; ++k) omega += triangle_solid_angle(u0, vertex(k), vertex(k + 1));
    return omega;
  };
  if (std::fabs(moment) >= r * norm * count) {  // the plane is beyond the sphere
    if (!known) sums.volume += r3 / 3 * face_solid_angle();
    return;
  }
  const Eigen::Vector3d normal = area2 / norm;
  const double height = moment / (norm * count);
  const double h = std::fabs(height);
  const Eigen::Vector3d foot = height * normal;
  bool meets = foot_inside(foot, normal);
  for (std::int32_t k = begin; k < end && !meets; ++k)
    meets = segment_in_ball(vertex(k), vertex(k + 1 == end ? begin : k + 1), r2);
  if (!meets) {
    if (!known && height != 0) sums.volume += r3 / 3 * face_solid_angle();
    return;
  }
  if (known && h <= ball.height_rounding) {  // which side of this plane the centre is on is unsure
    sums.unsure = true;
    return;
  }
  sums.boundary_in_ball = true;
  if (height == 0) return;  // a face through the centre adds no volume

  FacePlane pl;
  pl.h = h;
  pl.r = r;
  pl.r3 = r3;
  pl.a2 = (r - h) * (r + h);
  pl.cap = (r - h) / r;
  pl.cap_volume = (r - h) * (r - h) * (2 * r + h) / 6;
  double face_volume = 0;
  for (std::int32_t k = begin; k < end; ++k) {
    const EdgeDirection direction = edge(k);
    const double length = direction.length;
    if (!(length > 0)) continue;
    const Eigen::Vector3d& t = direction.t;
    const Eigen::Vector3d a = vertex(k) - foot;
    const double d_signed = normal.dot(a.cross(t));
    const double d = std::fabs(d_signed);
    if (d == 0) continue;  // p on the edge's line: a flat triangle
    const double sa = a.dot(t), sb = sa + length;
    const double rho = std::sqrt(h * h + d * d);
    double part;
    if (!known) {
      part = right_triangle_cone(pl, d, rho, sb) - right_triangle_cone(pl, d, rho, sa);
    } else if (pl.a2 <= d * d) {  // sectors only: the angle the edge spans, in one atan2
      part = -upper_half_angle(d * (sb - sa), d * d + sa * sb) * pl.cap_volume;
    } else {
      // The disc reaches the edge's line: its solid angle changes by O(1) within rho of
      // the line, so a centre near an edge (rho small against the edge's reach) would
      // take the rounding of d and h times length / rho.
      if (rho * rho < kEdgeMargin2 * (std::max(sa * sa, sb * sb) + d * d)) {
        sums.unsure = true;
        return;
      }
      part = right_triangle_cone_in_disc(pl, d, rho, sb) - right_triangle_cone_in_disc(pl, d, rho, sa);
    }
    face_volume += d_signed > 0 ? part : -part;
  }
  sums.volume += height > 0 ? face_volume : -face_volume;
}

/// The ball's volume.
double ball_volume(double r) {
  const double r3 = r * r * r;
  return 4.0 / 3.0 * std::numbers::pi * r3;
}

/// The overlap. winding: the centre's winding number about the surface, or -1 if unknown;
/// when known, faces that do not reach into the open ball may be left out, and a centre
/// within rounding of a reaching face's plane or near a reaching edge's line gives no value.
std::optional<double> overlap(const Eigen::Vector3d& centre, double radius,
                              std::span<const Eigen::Vector3d> vertices, std::span<const std::int32_t> face_offsets,
                              std::span<const std::int32_t> face_vertices, int winding) {
  const bool known = winding >= 0;
  if (!(radius > 0)) return 0;
  const double r = radius, r2 = r * r;
  const double ball = ball_volume(r);
  if (face_offsets.size() < 2 || vertices.empty()) return known ? winding * ball : 0;

  // The polyhedron lies in its vertices' hull: no overlap when their box misses the ball,
  // the whole polyhedron when they are all in the ball. (With the winding number known the
  // faces given may be a part of the surface: then the box only tells that none of them
  // reaches into the ball.)
  Eigen::Vector3d lo = vertices[0], hi = vertices[0];
  bool contained = !known;
  for (const Eigen::Vector3d& v : vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
    contained = contained && (v - centre).squaredNorm() <= r2;
  }
  const std::optional<Ball> reaching = ball_reaching(centre, r, lo, hi);
  if (!reaching) return known ? winding * ball : 0;
  const Ball& b = *reaching;

  const auto vertex = [&](std::int32_t k) -> Eigen::Vector3d {
    return vertices[static_cast<std::size_t>(face_vertices[static_cast<std::size_t>(k)])] - centre;
  };
  FaceSums sums;
  const std::size_t n_faces = face_offsets.size() - 1;
  for (std::size_t f = 0; f < n_faces; ++f) {
    const std::int32_t begin = face_offsets[f], end = face_offsets[f + 1];
    const auto edge = [&](std::int32_t k) { return edge_direction(vertex(k + 1 == end ? begin : k + 1) - vertex(k)); };
    add_face(vertex, edge, begin, end, b, known, contained, sums);
    if (sums.unsure) return std::nullopt;
  }
  if (known) return sphere_located_overlap(r, winding == 1, sums.volume);
  if (contained) return std::max(sums.polyhedron, 0.0);
  // No face in the open ball: the ball lies inside or outside, as the centre does.
  if (!sums.boundary_in_ball) return sums.volume > 0.5 * ball ? ball : 0.0;
  return std::clamp(sums.volume, 0.0, std::max(0.0, std::min(ball, sums.polyhedron)));
}

}  // namespace

double sphere_polyhedron_overlap(const Eigen::Vector3d& centre, double radius,
                                 std::span<const Eigen::Vector3d> vertices,
                                 std::span<const std::int32_t> face_offsets,
                                 std::span<const std::int32_t> face_vertices) {
  return *overlap(centre, radius, vertices, face_offsets, face_vertices, -1);  // declines only when located
}

std::optional<double> sphere_polyhedron_overlap_located(const Eigen::Vector3d& centre, double radius,
                                                        bool centre_inside,
                                                        std::span<const Eigen::Vector3d> vertices,
                                                        std::span<const std::int32_t> face_offsets,
                                                        std::span<const std::int32_t> face_vertices) {
  return overlap(centre, radius, vertices, face_offsets, face_vertices, centre_inside ? 1 : 0);
}

// Built for x86-64-v3 beside the baseline, its callees inlined so that the whole face term
// takes the build.
VFE_V3_CLONES_FLAT
std::optional<double> sphere_face_located_term(const Eigen::Vector3d& centre, double radius,
                                               std::span<const Eigen::Vector3d> polygon) {
  const auto n = static_cast<std::int32_t>(polygon.size());
  if (!(radius > 0) || n < 3) return 0;
  Eigen::Vector3d lo = polygon[0], hi = polygon[0];
  extend_box(polygon, lo, hi);
  const std::optional<Ball> reaching = ball_reaching(centre, radius, lo, hi);
  if (!reaching) return 0;
  const auto vertex = [&](std::int32_t k) -> Eigen::Vector3d { return polygon[static_cast<std::size_t>(k)] - centre; };
  const auto edge = [&](std::int32_t k) { return edge_direction(vertex(k + 1 == n ? 0 : k + 1) - vertex(k)); };
  FaceSums sums;
  add_face(vertex, edge, 0, n, *reaching, true, false, sums);
  if (sums.unsure) return std::nullopt;
  return sums.volume;
}

// Built for x86-64-v3 as the polygon's term is.
VFE_V3_CLONES_FLAT
std::optional<double> sphere_fan_located_term(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& apex,
                                              std::span<const Eigen::Vector3d> rim) {
  const auto n = static_cast<std::int32_t>(rim.size());
  if (!(radius > 0) || n < 2) return 0;
  // The fan lies in the box of its points: no triangle reaches the ball when the box misses it.
  Eigen::Vector3d lo = apex, hi = apex;
  extend_box(rim, lo, hi);
  const std::optional<Ball> reaching = ball_reaching(centre, radius, lo, hi);
  if (!reaching) return 0;
  if (n > kMostFanPoints) {  // rare: the triangles one by one
    double sum = 0;
    for (std::int32_t i = 0; i < n; ++i) {
      const std::array<Eigen::Vector3d, 3> triangle{apex, rim[static_cast<std::size_t>(i)],
                                                   rim[static_cast<std::size_t>(i + 1 == n ? 0 : i + 1)]};
      const std::optional<double> term = sphere_face_located_term(centre, radius, triangle);
      if (!term) return std::nullopt;
      sum += *term;
    }
    return sum;
  }
  const double r2 = reaching->r2;
  // The points relative to the centre, and the directions of the spokes (apex to rim
  // point) and of the rim's edges, each computed once: a spoke borders two triangles.
  std::array<Eigen::Vector3d, kMostFanPoints> u;
  std::array<EdgeDirection, kMostFanPoints> spoke, side;
  const Eigen::Vector3d u_apex = apex - centre;
  for (std::int32_t i = 0; i < n; ++i) u[static_cast<std::size_t>(i)] = rim[static_cast<std::size_t>(i)] - centre;
  for (std::int32_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i), next = static_cast<std::size_t>(i + 1 == n ? 0 : i + 1);
    spoke[k] = edge_direction(u[k] - u_apex);
    side[k] = edge_direction(u[next] - u[k]);
  }
  FaceSums sums;
  for (std::int32_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i), next = static_cast<std::size_t>(i + 1 == n ? 0 : i + 1);
    // Triangle (apex, P_i, P_i+1), the same test as the polygon's term first.
    const Eigen::Vector3d tri_lo = u_apex.cwiseMin(u[k]).cwiseMin(u[next]);
    const Eigen::Vector3d tri_hi = u_apex.cwiseMax(u[k]).cwiseMax(u[next]);
    if (tri_lo.cwiseMax(0.0).cwiseMin(tri_hi).squaredNorm() >= r2) continue;
    const auto vertex = [&](std::int32_t j) -> const Eigen::Vector3d& { return j == 0 ? u_apex : j == 1 ? u[k] : u[next]; };
    const auto edge = [&](std::int32_t j) {
      return j == 0 ? spoke[k] : j == 1 ? side[k] : EdgeDirection{-spoke[next].t, spoke[next].length};
    };
    add_face(vertex, edge, 0, 3, *reaching, true, false, sums);
    if (sums.unsure) return std::nullopt;
  }
  return sums.volume;
}

double sphere_located_overlap(double radius, bool centre_inside, double face_terms) {
  if (!(radius > 0)) return 0;
  const double ball = ball_volume(radius);
  return std::clamp(face_terms + (centre_inside ? ball : 0.0), 0.0, ball);
}

double sphere_tetrahedron_overlap(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& a,
                                  const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const double orientation = (b - a).cross(c - a).dot(d - a);
  if (orientation == 0 || !std::isfinite(orientation)) return 0;
  const std::array<Eigen::Vector3d, 4> vertices{a, b, c, d};
  static constexpr std::array<std::int32_t, 5> kOffsets{0, 3, 6, 9, 12};
  // Outward faces of a positively oriented (a, b, c, d), and the same reversed.
  static constexpr std::array<std::int32_t, 12> kPositive{0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  static constexpr std::array<std::int32_t, 12> kNegative{0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
  return sphere_polyhedron_overlap(centre, radius, vertices, kOffsets, orientation > 0 ? kPositive : kNegative);
}

}  // namespace vfe::kernels

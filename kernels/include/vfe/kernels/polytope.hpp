// Small convex polytopes clipped by planes (the r3d scheme of Powell & Abel 2015): each
// vertex keeps its 3 neighbours in a fixed order, so a clip is one pass over the vertices
// and the faces are recovered by walking the neighbour graph. Exact to round-off, no
// allocation; and the overlaps of boxes and tetrahedra with polyhedral cells built on it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <cstdint>
#include <span>

namespace vfe::kernels {

/// Volume and first moments (integral of x dV) of a body.
struct VolumeMoments {
  double volume = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  /// Centre of volume; the origin when the volume is 0.
  Eigen::Vector3d centroid() const {
    return volume != 0 ? Eigen::Vector3d(first / volume) : Eigen::Vector3d(Eigen::Vector3d::Zero());
  }
};

/// Quadrature rules on a tetrahedron of a stated polynomial degree (exact for polynomials
/// of that total degree): 1 (centroid, 1 point), 2 (4 points), 5 (14 points, positive
/// weights: Walkington 2000 / Keast). Points as barycentric weights of the 4 corners.
struct TetrahedronRule {
  int degree = 0;
  int size = 0;
  std::array<std::array<double, 4>, 14> points{};
  std::array<double, 14> weights{};  ///< sum to 1 (fractions of the tetrahedron's volume)
};
/// The rule of the smallest listed degree >= `degree` (degree <= 5).
const TetrahedronRule& tetrahedron_rule(int degree);

/// Convex polytope of at most kCapacity vertices, each of degree 3 (a simple polytope, as
/// clipping a tetrahedron or a box by planes keeps it). About 5 kB, on the stack.
class ConvexPolytope {
 public:
  static constexpr int kCapacity = 128;

  ConvexPolytope() = default;
  /// The tetrahedron (a, b, c, d), either orientation (a flat one is empty).
  static ConvexPolytope tetrahedron(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                    const Eigen::Vector3d& d);
  /// The box [lo, hi] (empty if lo >= hi on some axis).
  static ConvexPolytope box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

  /// Keeps the part with normal . x <= offset (normal need not be unit). Returns false
  /// when the result would exceed kCapacity vertices (about 60 clipping planes in all):
  /// the polytope is then left empty and overflowed() is true.
  bool clip(const Eigen::Vector3d& normal, double offset);
  /// Keeps the part inside the box [lo, hi] (6 clips).
  bool clip_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);
  /// Each plane (n, d) as a 4-vector (n_x, n_y, n_z, d), keeping n . x <= d.
  bool clip_halfspaces(std::span<const Eigen::Vector4d> planes);

  bool empty() const { return n_ == 0; }
  bool overflowed() const { return overflow_; }
  int size() const { return n_; }
  const Eigen::Vector3d& vertex(int i) const { return v_[static_cast<std::size_t>(i)].pos; }
  Eigen::AlignedBox3d bounds() const;

  /// Volume (>= 0, to round-off) and first moments, from the fan tetrahedra of the faces
  /// about vertex 0 (less round-off than about the origin).
  VolumeMoments moments() const;
  double volume() const { return moments().volume; }

  /// Calls f(o, a, b, c) for positively oriented tetrahedra that tile the polytope (the
  /// fans of its faces about vertex o = vertex 0; faces through it are skipped).
  template <class F>
  void for_each_tetrahedron(F&& f) const;

  /// Integral of f(x) over the polytope by `rule` on each tetrahedron of
  /// for_each_tetrahedron; exact for polynomials of the rule's degree.
  template <class F>
  double integrate(F&& f, const TetrahedronRule& rule) const;

 private:
  struct Vertex {
    Eigen::Vector3d pos;
    std::array<std::int16_t, 3> nbr;  ///< counter-clockwise seen from outside
  };
  std::array<Vertex, kCapacity> v_;
  int n_ = 0;
  bool overflow_ = false;
};

/// Integral of f over the tetrahedron (a, b, c, d) by `rule` (volume taken positive).
template <class F>
double integrate_tetrahedron(F&& f, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                             const Eigen::Vector3d& d, const TetrahedronRule& rule) {
  const double volume = std::fabs((b - a).dot((c - a).cross(d - a))) / 6.0;
  double sum = 0;
  for (int q = 0; q < rule.size; ++q) {
    const auto& w = rule.points[static_cast<std::size_t>(q)];
    sum += rule.weights[static_cast<std::size_t>(q)] * f(Eigen::Vector3d(w[0] * a + w[1] * b + w[2] * c + w[3] * d));
  }
  return volume * sum;
}

template <class F>
void ConvexPolytope::for_each_tetrahedron(F&& f) const {
  if (n_ < 4) return;
  // Walk every face once (an edge slot is marked when its face has been walked).
  std::array<std::array<bool, 3>, kCapacity> marked{};
  const Eigen::Vector3d& origin = v_[0].pos;
  const auto slot_of = [&](int at, int neighbour) {
    const auto& nb = v_[static_cast<std::size_t>(at)].nbr;
    return nb[0] == neighbour ? 0 : nb[1] == neighbour ? 1 : 2;
  };
  for (int start = 0; start < n_; ++start) {
    for (int slot = 0; slot < 3; ++slot) {
      if (marked[static_cast<std::size_t>(start)][static_cast<std::size_t>(slot)]) continue;
      int cur = start, next_slot = slot;
      marked[static_cast<std::size_t>(cur)][static_cast<std::size_t>(next_slot)] = true;
      int next = v_[static_cast<std::size_t>(cur)].nbr[static_cast<std::size_t>(next_slot)];
      const bool through_origin = start == 0;
      // Step along the face: from next, the edge after the one back to cur.
      const auto advance = [&] {
        const int back = slot_of(next, cur);
        cur = next;
        next_slot = (back + 1) % 3;
        marked[static_cast<std::size_t>(cur)][static_cast<std::size_t>(next_slot)] = true;
        next = v_[static_cast<std::size_t>(cur)].nbr[static_cast<std::size_t>(next_slot)];
      };
      advance();
      bool touches_origin = through_origin || cur == 0;
      const Eigen::Vector3d& first = v_[static_cast<std::size_t>(start)].pos;
      // The walk turns clockwise seen from outside, so (first, next, cur) is positive
      // seen from inside; a face through vertex 0 is flat seen from it.
      while (next != start) {
        touches_origin = touches_origin || next == 0;
        if (!touches_origin)
          f(origin, first, v_[static_cast<std::size_t>(next)].pos, v_[static_cast<std::size_t>(cur)].pos);
        advance();
      }
    }
  }
}

template <class F>
double ConvexPolytope::integrate(F&& f, const TetrahedronRule& rule) const {
  double sum = 0;
  for_each_tetrahedron([&](const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c) { sum += integrate_tetrahedron(f, o, a, b, c, rule); });
  return sum;
}

/// Volume of the tetrahedron (a, b, c, d) inside the box [lo, hi], signed by the
/// tetrahedron's orientation (positive when (b - a) . ((c - a) x (d - a)) > 0). Exact to
/// round-off; 0 when the bounding boxes do not overlap or the tetrahedron is flat.
double tetrahedron_box_overlap(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& d, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Volume of the tetrahedron inside the convex region {x : n_k . x <= d_k for all k}
/// (planes as (n, d) 4-vectors), signed by orientation as above. At most ~56 planes.
double tetrahedron_halfspaces_overlap(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                      const Eigen::Vector3d& d, std::span<const Eigen::Vector4d> planes);

/// Signed volume of the tetrahedron (a, b, c, d): (b - a) . ((c - a) x (d - a)) / 6.
inline double signed_tetrahedron_volume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                        const Eigen::Vector3d& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

/// A polyhedral cell as signed tetrahedra: tets[4 t .. 4 t + 3] are the corners of
/// tetrahedron t; each counts with the sign of its orientation, so the cell is their
/// signed union (OpenFOAM's decomposition: cell centre, face apex, two consecutive face
/// points, in either order as long as the signed volumes sum to the cell's volume).
using TetrahedraView = std::span<const Eigen::Vector3d>;

/// Calls f(a, b, c, d) for the signed tetrahedra of the polyhedron bounded by planar or
/// warped faces (the layout of sphere_polyhedron_overlap: face f is vertices[face_vertices[k]],
/// k in [face_offsets[f], face_offsets[f + 1]), counter-clockwise seen from outside):
/// apex = the mean of all referenced vertices; a triangle gives (apex, p0, p1, p2), a
/// larger face (apex, face centre, p_i, p_i+1) with the face centre the mean of its
/// vertices (so two cells sharing a face split it alike). Positive tetrahedra for a convex
/// cell; the signed sum is the polyhedron's volume for any closed oriented surface.
template <class F>
void for_each_face_tetrahedron(std::span<const Eigen::Vector3d> vertices, std::span<const std::int32_t> face_offsets,
                               std::span<const std::int32_t> face_vertices, F&& f) {
  if (face_offsets.size() < 2) return;
  const auto at = [&](std::int32_t k) -> const Eigen::Vector3d& {
    return vertices[static_cast<std::size_t>(face_vertices[static_cast<std::size_t>(k)])];
  };
  const std::int32_t total = face_offsets.back() - face_offsets.front();
  if (total <= 0) return;
  Eigen::Vector3d apex = Eigen::Vector3d::Zero();
  for (std::int32_t k = face_offsets.front(); k < face_offsets.back(); ++k) apex += at(k);
  apex /= double(total);
  for (std::size_t face = 0; face + 1 < face_offsets.size(); ++face) {
    const std::int32_t begin = face_offsets[face], end = face_offsets[face + 1];
    if (end - begin < 3) continue;
    if (end - begin == 3) {
      f(apex, at(begin), at(begin + 1), at(begin + 2));
      continue;
    }
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::int32_t k = begin; k < end; ++k) centre += at(k);
    centre /= double(end - begin);
    for (std::int32_t k = begin; k < end; ++k) f(apex, centre, at(k), at(k + 1 == end ? begin : k + 1));
  }
}

/// Volume of the box [lo, hi] inside a cell given as signed tetrahedra (TetrahedraView):
/// the signed sum of each tetrahedron's box overlap. Exact to round-off and additive: over
/// cells that tile a region the overlaps sum to the box's volume inside the region.
double box_polyhedron_overlap(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, TetrahedraView tets);

/// The same for a cell given by its faces (for_each_face_tetrahedron's layout).
double box_polyhedron_overlap(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                              std::span<const Eigen::Vector3d> vertices, std::span<const std::int32_t> face_offsets,
                              std::span<const std::int32_t> face_vertices);

}  // namespace vfe::kernels

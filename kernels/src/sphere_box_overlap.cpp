// Exact overlap volume of a sphere with axis-aligned boxes and rectilinear cell patches.
//
// Everything is reduced to the volume of the unit ball in a "corner"
//
//     K(a, b, c) = |{ |p| <= 1, X >= a, Y >= b, Z >= c }|,   0 <= a, b, c < 1,
//
// which is only ever evaluated on these non-negative thresholds, where it is well
// conditioned.  Negative thresholds are removed with the reflection symmetry of the ball
// along each axis, 1[X >= -t] = 1 - 1[X' >= t] with X' = -X, so that every quantity
// becomes a signed sum of K, of the wedge W(a, b) = |{ |p| <= 1, X >= a, Y >= b }|
// (= 2 K(a, b, 0) by reflection in the unbounded axis), of a spherical cap and of the
// whole ball.
//
// Closed form of K.  Let D = 1 - a^2 - b^2 - c^2 (> 0, else K = 0) and
// s_ab = sqrt(1 - a^2 - b^2) = sqrt(D + c^2), and cyclically.  The region is bounded by
// a curved spherical triangle S and by three planar faces.  The divergence theorem
// with the field p/3 gives
//
//     3 K = |S| - a |F_x| - b |F_y| - c |F_z|.
//
// |S| follows from Gauss-Bonnet: the three boundary arcs lie on the small circles
// X = a, ... (geodesic curvature a / sqrt(1 - a^2), so the integrated curvature along
// the arc of X = a is a * phi_a, phi_a being the arc's central angle in its own plane)
// and the exterior angle at the vertex (a, b, s_ab) is pi/2 + atan2(ab, s_ab).  Each
// planar face is a disk cut by a quadrant; its area follows from the 2-D divergence
// theorem: |F_x| = ((1 - a^2) phi_a - b l_ab - c l_ca) / 2 with the straight edge
// lengths l_ab = s_ab - c = D / (s_ab + c), ...  Altogether
//
//     3 K = pi/2 - [atan2(ab, s_ab) + atan2(bc, s_bc) + atan2(ca, s_ca)]
//           - [a (3 - a^2) phi_a + b (3 - b^2) phi_b + c (3 - c^2) phi_c] / 2
//           + ab l_ab + bc l_bc + ca l_ca,
//
// with phi_a = atan2(s_ab s_ca - bc, b s_ca + c s_ab) and s_ab s_ca - bc rewritten as
// (D + b^2 + c^2) D / (s_ab s_ca + bc), which is free of cancellation.  All square roots
// and 1 - a^2 factors are formed from D, so the data stay geometrically consistent even
// when the corner point (a, b, c) is within round-off of the sphere; the result is
// accurate to a few 1e-16 in absolute terms (relative accuracy degrades for overlaps far
// below that level, which are then tiny in absolute terms).
#include "vfe/kernels/sphere_box_overlap.hpp"
#include "vfe/kernels/v3_clones.hpp"

#include "ratio_angle.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vfe::kernels {
namespace {

using detail::kAngleHi;
using detail::kAngleLo;
using detail::ratio_angle;

constexpr double kPi = std::numbers::pi;
constexpr double kUnitBallVolume = 4.0 * std::numbers::pi / 3.0;

/// Threshold value meaning "no bound on this axis".
constexpr double kUnbounded = -1.0;

// max(x, 0), min(x, y) and "x where d > 0, else 0" without a branch. The exact method meets
// both sides of these at random from sphere to sphere, and GCC compiles the plain
// std::max(x, 0.0) or d > 0 ? x : 0 feeding arithmetic into branches it then mispredicts.
#if defined(__SSE2__)
inline double positive_part(double x) { return _mm_cvtsd_f64(_mm_max_sd(_mm_set_sd(x), _mm_setzero_pd())); }
inline double smaller(double x, double y) { return _mm_cvtsd_f64(_mm_min_sd(_mm_set_sd(x), _mm_set_sd(y))); }
inline double where_positive(double d, double x) {
  return _mm_cvtsd_f64(_mm_and_pd(_mm_cmpgt_sd(_mm_set_sd(d), _mm_setzero_pd()), _mm_set_sd(x)));
}
#else
inline double positive_part(double x) { return x > 0.0 ? x : 0.0; }
inline double smaller(double x, double y) { return x < y ? x : y; }
inline double where_positive(double d, double x) { return d > 0.0 ? x : 0.0; }
#endif

/// ratio_angle of two pairs at once, (num0, den0) into out0 and (num1, den1) into out1:
/// with SSE2 the same operations on both lanes of a register, so the same bits as two
/// calls at about the cost of one.
inline void ratio_angle_pair(double num0, double den0, double num1, double den1, double& out0, double& out1) {
#if defined(__SSE2__)
  const __m128d num = _mm_set_pd(num1, num0), den = _mm_set_pd(den1, den0);
  const __m128d one = _mm_set1_pd(1.0);
  const __m128d swap = _mm_cmpgt_pd(num, den);
  const __m128d small = _mm_min_pd(num, den), large = _mm_max_pd(num, den);
  const __m128d q = _mm_div_pd(small, _mm_add_pd(large, _mm_and_pd(_mm_cmpeq_pd(large, _mm_setzero_pd()), one)));
  const __m128i k = _mm_cvttpd_epi32(_mm_add_pd(_mm_mul_pd(_mm_set1_pd(8.0), q), _mm_set1_pd(0.5)));
  const __m128d c = _mm_mul_pd(_mm_set1_pd(0.125), _mm_cvtepi32_pd(k));
  const __m128d u = _mm_div_pd(_mm_sub_pd(q, c), _mm_add_pd(one, _mm_mul_pd(q, c)));
  const __m128d u2 = _mm_mul_pd(u, u);
  __m128d poly = _mm_mul_pd(u2, _mm_set1_pd(1.0 / 13));
  for (const double coefficient : {-1.0 / 11, 1.0 / 9, -1.0 / 7, 1.0 / 5})
    poly = _mm_mul_pd(u2, _mm_add_pd(_mm_set1_pd(coefficient), poly));
  const __m128d tail = _mm_mul_pd(_mm_mul_pd(u, u2), _mm_add_pd(_mm_set1_pd(-1.0 / 3), poly));
  // (u + tail) with the sign of the swapped lanes flipped: the multiply by -1 of ratio_angle.
  const __m128d signed_sum = _mm_xor_pd(_mm_add_pd(u, tail), _mm_and_pd(swap, _mm_set1_pd(-0.0)));
  const int swaps = _mm_movemask_pd(swap);
  const int at0 = _mm_cvtsi128_si32(k) + 9 * (swaps & 1);
  const int at1 = _mm_cvtsi128_si32(_mm_shuffle_epi32(k, 1)) + 9 * (swaps >> 1);
  const __m128d hi = _mm_set_pd(kAngleHi[at1], kAngleHi[at0]), lo = _mm_set_pd(kAngleLo[at1], kAngleLo[at0]);
  const __m128d angle = _mm_add_pd(hi, _mm_add_pd(lo, signed_sum));
  out0 = _mm_cvtsd_f64(angle);
  out1 = _mm_cvtsd_f64(_mm_unpackhi_pd(angle, angle));
#else
  out0 = ratio_angle(num0, den0);
  out1 = ratio_angle(num1, den1);
#endif
}

/// K(a, b, c) above, for a, b, c in [0, 1].
double unit_ball_corner(double a, double b, double c) {
  const double a2 = a * a, b2 = b * b, c2 = c * c;
  const double d = ((1.0 - a2) - b2) - c2;
  if (!(d > 0.0)) return 0.0;
  const double sab = std::sqrt(d + c2);
  const double sbc = std::sqrt(d + a2);
  const double sca = std::sqrt(d + b2);
  const double ab = a * b, bc = b * c, ca = c * a;

  // Sum of the three exterior-angle excesses atan2(ab, s_ab) + ...; it lies in
  // [0, pi/2] because |S| >= 0.  With all three present it is the argument of
  // (s_ab + i ab)(s_bc + i bc)(s_ca + i ca).
  double exterior = 0.0;
  if (ab > 0.0 && bc > 0.0 && ca > 0.0) {
    const double re1 = sab * sbc - ab * bc, im1 = sab * bc + ab * sbc;
    const double re = re1 * sca - im1 * ca, im = re1 * ca + im1 * sca;
    exterior = ratio_angle(std::max(im, 0.0), std::max(re, 0.0));
  } else {
    if (ab > 0.0) exterior += ratio_angle(ab, sab);
    if (bc > 0.0) exterior += ratio_angle(bc, sbc);
    if (ca > 0.0) exterior += ratio_angle(ca, sca);
  }

  // Arc angles: phi_a = atan2(s_ab s_ca - bc, b s_ca + c s_ab), where
  // s_ab s_ca - bc = (1 - a^2) d / (s_ab s_ca + bc) and 1 - a^2 = d + b^2 + c^2, which
  // keeps the small angles free of cancellation and consistent with d.
  double arcs = 0.0;
  if (a > 0.0)
    arcs += a * (3.0 - a2) *
            ratio_angle((d + b2 + c2) * d, (sab * sca + bc) * (b * sca + c * sab));
  if (b > 0.0)
    arcs += b * (3.0 - b2) *
            ratio_angle((d + a2 + c2) * d, (sab * sbc + ca) * (a * sbc + c * sab));
  if (c > 0.0)
    arcs += c * (3.0 - c2) *
            ratio_angle((d + a2 + b2) * d, (sca * sbc + ab) * (a * sbc + b * sca));

  // Straight edges: l_ab = s_ab - c = d / (s_ab + c), ...
  double edges = 0.0;
  if (ab > 0.0) edges += ab / (sab + c);
  if (bc > 0.0) edges += bc / (sbc + a);
  if (ca > 0.0) edges += ca / (sca + b);
  edges *= d;

  const double three_k = (0.5 * kPi - exterior) - 0.5 * arcs + edges;
  return three_k > 0.0 ? three_k / 3.0 : 0.0;
}

/// The terms of the wedge W(p, q) = |{ |x| <= 1, X_p >= p, X_q >= q }| = 2 K(p, q, 0),
/// p, q in [0, 1]: s = sqrt(1 - p^2 - q^2), the arc angles of the planes (arc_p on X_p = p:
/// atan2(s, q); arc_q on X_q = q: atan2(s, p)) and the exterior angle atan2(pq, s) at the
/// vertex (p, q, s).  With c = 0 the arc angles of K reduce to these and its edge term to
/// pq s:  3 W / 2 = pi/2 - atan2(pq, s) - [p (3 - p^2) arc_p + q (3 - q^2) arc_q] / 2 + pq s.
/// The terms are also those of every corner K(p, q, r): see corner_from_wedges.
/// Computed whether or not the wedge reaches the ball (then with s = 0, and every output
/// 0): the exact method's spheres meet both cases at random, and a branch the processor
/// cannot predict costs more than the few operations.
struct Wedge {
  double present = 0;  ///< 1 when 1 - p^2 - q^2 > 0, else 0 (the wedge misses the ball)
  double s = 0, arc_p = 0, arc_q = 0, exterior = 0, volume = 0;
};

/// The wedge's root: whether it reaches the ball, and s.
inline Wedge wedge_root(double p, double q) {
  Wedge w;
  const double d = (1.0 - p * p) - q * q;
  w.present = where_positive(d, 1.0);
  w.s = std::sqrt(positive_part(d));
  return w;
}

/// The wedge's volume from its root and angles.
inline void wedge_volume(double p, double q, Wedge& w) {
  const double arcs = p * (3.0 - p * p) * w.arc_p + q * (3.0 - q * q) * w.arc_q;
  const double three_half_w = (0.5 * kPi - w.exterior) - 0.5 * arcs + p * q * w.s;
  w.volume = positive_part(three_half_w) * (2.0 / 3.0) * w.present;
}

inline Wedge wedge_terms(double p, double q) {
  Wedge w = wedge_root(p, q);
  w.arc_p = ratio_angle(w.s, q);
  w.arc_q = ratio_angle(w.s, p);
  w.exterior = ratio_angle(p * q, w.s);
  wedge_volume(p, q, w);
  return w;
}

/// W(a, b) = |{ |p| <= 1, X >= a, Y >= b }|, for a, b in [0, 1].
double unit_ball_wedge(double a, double b) { return wedge_terms(a, b).volume; }

/// K(a, b, c), a, b, c in [0, 1], from the terms of the wedges of its three pairs (x, y),
/// (y, z), (z, x), which hold all it needs: its square roots s_ab, s_bc, s_ca are theirs,
/// its exterior angles are theirs, and each of its arc angles is the sum of the two wedges'
/// arcs on that plane less pi/2 (on X = a the arc runs from (b, s_ab) to (s_ca, c), at
/// angles atan2(s_ab, b) and pi/2 - atan2(s_ca, c) from the Y axis).  So K costs no angle of
/// its own; the difference of angles keeps the absolute accuracy of unit_ball_corner.
/// Branch-free as wedge_terms.
inline double corner_from_wedges(double a, double b, double c, const Wedge& xy, const Wedge& yz, const Wedge& zx) {
  const double a2 = a * a, b2 = b * b, c2 = c * c;
  const double d = ((1.0 - a2) - b2) - c2;
  const double exterior = (xy.exterior + yz.exterior) + zx.exterior;
  const double phi_a = (xy.arc_p + zx.arc_q) - 0.5 * kPi;
  const double phi_b = (xy.arc_q + yz.arc_p) - 0.5 * kPi;
  const double phi_c = (yz.arc_q + zx.arc_p) - 0.5 * kPi;
  const double arcs = a * (3.0 - a2) * phi_a + b * (3.0 - b2) * phi_b + c * (3.0 - c2) * phi_c;
  // Straight edges l_ab = s_ab - c, ...
  const double edges = a * b * (xy.s - c) + b * c * (yz.s - a) + c * a * (zx.s - b);
  const double three_k = (0.5 * kPi - exterior) - 0.5 * arcs + edges;
  // A pair missing the ball while d > 0 is round-off at a corner on the sphere: K ~ 0.
  const double reached = where_positive(d, xy.present * yz.present * zx.present);
  return positive_part(three_k) / 3.0 * reached;
}

/// unit_ball_octants' wedges and corner when all three planes cut (v[3], v[5], v[6], v[7]).
/// Out of line: inlined beside the one-wedge cases it makes the compiler spill.
VFE_V3_CLONES [[gnu::noinline]] void three_planes(const double t[3], double v[8]) {
  const double a = t[0], b = t[1], c = t[2];
  Wedge xy = wedge_root(a, b), yz = wedge_root(b, c), zx = wedge_root(c, a);
  // wedge_terms' 9 angles, two at a time.
  ratio_angle_pair(xy.s, b, xy.s, a, xy.arc_p, xy.arc_q);
  ratio_angle_pair(yz.s, c, yz.s, b, yz.arc_p, yz.arc_q);
  ratio_angle_pair(zx.s, a, zx.s, c, zx.arc_p, zx.arc_q);
  ratio_angle_pair(a * b, xy.s, b * c, yz.s, xy.exterior, yz.exterior);
  zx.exterior = ratio_angle(c * a, zx.s);
  wedge_volume(a, b, xy);
  wedge_volume(b, c, yz);
  wedge_volume(c, a, zx);
  v[3] = xy.volume;
  v[6] = yz.volume;
  v[5] = zx.volume;
  v[7] = corner_from_wedges(a, b, c, xy, yz, zx);
}

/// Cap of the unit ball beyond the plane X = t, t in [0, 1].
double unit_ball_cap(double t) {
  const double h = 1.0 - t;
  return kPi / 3.0 * h * h * (2.0 + t);
}

/// Volume of the unit ball in {X >= tx, Y >= ty, Z >= tz}, each threshold either in
/// [0, 1) or kUnbounded (negative).
double corner_term(double tx, double ty, double tz) {
  const bool bx = tx >= 0.0, by = ty >= 0.0, bz = tz >= 0.0;
  switch (int(bx) + int(by) + int(bz)) {
    case 0:
      return kUnitBallVolume;
    case 1:
      return unit_ball_cap(bx ? tx : (by ? ty : tz));
    case 2:
      return bx ? unit_ball_wedge(tx, by ? ty : tz) : unit_ball_wedge(ty, tz);
    default:
      return unit_ball_corner(tx, ty, tz);
  }
}

/// Signed half-line terms of one axis: the indicator of the axis range equals
/// sum_k sign[k] * 1[+-X >= t[k]] (the reflection does not matter for the ball).
struct AxisTerms {
  double t[3];
  double sign[3];
  int n = 0;
  void add(double s, double threshold) {
    if (threshold >= 1.0) return;  // the half-line misses the ball
    t[n] = threshold;
    sign[n] = s;
    ++n;
  }
};

/// Terms of the half-line X <= x (x clamped to [-1, 1]).
AxisTerms below_terms(double x) {
  AxisTerms terms;
  if (x <= -1.0) return terms;
  if (x >= 1.0) {
    terms.add(1.0, kUnbounded);
  } else if (x <= 0.0) {
    terms.add(1.0, -x);  // reflected: X' >= -x
  } else {
    terms.add(1.0, kUnbounded);
    terms.add(-1.0, x);
  }
  return terms;
}

/// Terms of the interval l <= X <= h (l < h, both clamped to [-1, 1]).
AxisTerms interval_terms(double l, double h) {
  AxisTerms terms;
  if (h <= -1.0 || l >= 1.0) return terms;
  if (h <= 0.0) {  // reflected: -h <= X' <= -l
    terms.add(1.0, -h);
    if (l > -1.0) terms.add(-1.0, -l);
  } else if (l >= 0.0) {
    terms.add(1.0, l);
    terms.add(-1.0, h);
  } else {  // l < 0 < h
    terms.add(1.0, kUnbounded);
    terms.add(-1.0, h);
    if (l > -1.0) terms.add(-1.0, -l);
  }
  return terms;
}

double combine(const AxisTerms& tx, const AxisTerms& ty, const AxisTerms& tz) {
  double sum = 0.0;
  for (int k = 0; k < tz.n; ++k)
    for (int j = 0; j < ty.n; ++j)
      for (int i = 0; i < tx.n; ++i)
        sum += tx.sign[i] * ty.sign[j] * tz.sign[k] * corner_term(tx.t[i], ty.t[j], tz.t[k]);
  return sum;
}

double clamp_unit(double v) { return v < -1.0 ? -1.0 : (v > 1.0 ? 1.0 : v); }

/// Orthant volume for arguments already clamped to [-1, 1].
double orthant_clamped(double x, double y, double z) {
  if (x <= -1.0 || y <= -1.0 || z <= -1.0) return 0.0;
  return combine(below_terms(x), below_terms(y), below_terms(z));
}

/// Per-node terms of the half-lines X <= x_i of one patch axis (cf. below_terms):
/// u = 1 if the unbounded term is present, s = sign of the threshold term (0 if absent),
/// t = its threshold, cap = s != 0 ? cap(t) : 0.  Arrays live in the caller's scratch.
struct AxisNodes {
  double *t = nullptr, *s = nullptr, *u = nullptr, *cap = nullptr;
  /// Fills the arrays from `storage` (advanced by 4 m); returns whether any u is 1.
  bool setup(const double* coords, std::size_t m, double c, double radius, double*& storage) {
    t = storage;
    s = t + m;
    u = s + m;
    cap = u + m;
    storage = cap + m;
    bool any_u = false;
    for (std::size_t i = 0; i < m; ++i) {
      const double w = clamp_unit((coords[i] - c) / radius);
      t[i] = 0.0;
      s[i] = 0.0;
      u[i] = 0.0;
      cap[i] = 0.0;
      if (w <= -1.0) continue;
      if (w >= 1.0) {
        u[i] = 1.0;
      } else if (w <= 0.0) {
        t[i] = -w;
        s[i] = 1.0;
        cap[i] = unit_ball_cap(-w);
      } else {
        t[i] = w;
        s[i] = -1.0;
        u[i] = 1.0;
        cap[i] = unit_ball_cap(w);
      }
      any_u = any_u || u[i] != 0.0;
    }
    return any_u;
  }
};

/// Distance from c to the interval [l, h] along one axis.
double gap(double c, double l, double h) { return l > c ? l - c : (c > h ? c - h : 0.0); }

/// Distance from c to the farther end of [l, h].
double reach(double c, double l, double h) { return std::max(c - l, h - c); }

/// Per-cell data of one patch axis for the exact early answers: squared distance from
/// the centre to the cell's slab (gap2) and to its farther face (reach2), the width, and
/// whether the slab holds the ball's extent along the axis.
struct AxisCells {
  double *gap2 = nullptr, *reach2 = nullptr, *width = nullptr, *holds = nullptr;
  void setup(const double* coords, std::size_t n, double c, double radius, double*& storage) {
    gap2 = storage;
    reach2 = gap2 + n;
    width = reach2 + n;
    holds = width + n;
    storage = holds + n;
    for (std::size_t i = 0; i < n; ++i) {
      const double l = coords[i], h = coords[i + 1];
      const double g = gap(c, l, h), f = reach(c, l, h);
      gap2[i] = g * g;
      reach2[i] = f * f;
      width[i] = h - l;
      holds[i] = c - l >= radius && h - c >= radius ? 1.0 : 0.0;
    }
  }
};

}  // namespace

double unit_ball_orthant_volume(double x, double y, double z) {
  if (std::isnan(x) || std::isnan(y) || std::isnan(z)) return std::nan("");
  const double v = orthant_clamped(clamp_unit(x), clamp_unit(y), clamp_unit(z));
  return std::clamp(v, 0.0, kUnitBallVolume);
}

// Built for x86-64-v3 beside the baseline, as three_planes.
VFE_V3_CLONES
void unit_ball_octants(double a, double b, double c, double volumes[8]) {
  // Each axis reflected so that its plane lies at t >= 0: the far side X' >= t is then the
  // smaller part, and v[m] below, the ball in the far sides of the axes in m (m = 0: the
  // whole ball), is a cap, wedge or corner evaluated where it is well conditioned. A plane
  // at |t| >= 1 (or NaN) misses the ball: t = 1 makes its cap exactly 0.
  const double in[3] = {a, b, c};
  double t[3];
  unsigned flip = 0, cut = 0;
  for (int d = 0; d < 3; ++d) {
    const double w = std::abs(in[d]);
    flip |= unsigned(std::signbit(in[d])) << d;
    cut |= unsigned(w < 1.0) << d;
    t[d] = smaller(w, 1.0);  // NaN gives 1
  }
  double v[8] = {kUnitBallVolume, unit_ball_cap(t[0]), unit_ball_cap(t[1]), 0.0, unit_ball_cap(t[2]), 0.0, 0.0, 0.0};
  // One branch on which planes cut (the same for every sphere spanning 2 cells per axis);
  // inside, none: which wedges and corners reach the ball varies at random.
  switch (cut) {
    case 7: three_planes(t, v); break;
    case 3: v[3] = wedge_terms(t[0], t[1]).volume; break;
    case 6: v[6] = wedge_terms(t[1], t[2]).volume; break;
    case 5: v[5] = wedge_terms(t[2], t[0]).volume; break;
    default: break;  // at most one plane: its cap
  }
  // Inclusion-exclusion one axis at a time: near side = ball - far side. Every
  // intermediate value is the volume of a region, at least half of the term it is taken
  // from (the near side holds the mirror image of the far side), so nothing cancels.
  for (unsigned bit = 1; bit < 8; bit <<= 1)
    for (unsigned m = 0; m < 8; ++m)
      if (!(m & bit)) v[m] -= v[m | bit];
  for (unsigned m = 0; m < 8; ++m) volumes[m ^ flip] = smaller(positive_part(v[m]), kUnitBallVolume);
}

double sphere_box_overlap(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& lo,
                          const Eigen::Vector3d& hi) {
  if (!(radius > 0.0)) return 0.0;
  if (!(lo.x() < hi.x() && lo.y() < hi.y() && lo.z() < hi.z())) return 0.0;

  const double r2 = radius * radius;
  double near2 = 0.0, far2 = 0.0;
  bool ball_inside = true;
  // Summed z, y, x: the same association as the per-cell tests of the patch routine.
  for (int a = 2; a >= 0; --a) {
    const double g = gap(centre[a], lo[a], hi[a]);
    const double f = reach(centre[a], lo[a], hi[a]);
    near2 += g * g;
    far2 += f * f;
    ball_inside = ball_inside && centre[a] - lo[a] >= radius && hi[a] - centre[a] >= radius;
  }
  if (near2 >= r2) return 0.0;  // tangent or apart
  const double box_volume = (hi.x() - lo.x()) * ((hi.y() - lo.y()) * (hi.z() - lo.z()));
  if (far2 <= r2) return box_volume;  // all corners inside the ball
  const double r3 = r2 * radius;
  const double ball_volume = kUnitBallVolume * r3;
  if (ball_inside) return ball_volume;

  AxisTerms terms[3];
  for (int a = 0; a < 3; ++a)
    terms[a] = interval_terms(clamp_unit((lo[a] - centre[a]) / radius),
                              clamp_unit((hi[a] - centre[a]) / radius));
  const double v = combine(terms[0], terms[1], terms[2]) * r3;
  return std::clamp(v, 0.0, std::min(box_volume, ball_volume));
}

void sphere_patch_overlaps_into(const Eigen::Vector3d& centre, double radius, const double* x,
                                int nx, const double* y, int ny, const double* z, int nz,
                                std::vector<double>& scratch, std::vector<double>& volumes_out) {
  const std::size_t sx = static_cast<std::size_t>(std::max(nx, 0));
  const std::size_t sy = static_cast<std::size_t>(std::max(ny, 0));
  const std::size_t sz = static_cast<std::size_t>(std::max(nz, 0));
  volumes_out.assign(sx * sy * sz, 0.0);
  if (volumes_out.empty() || !(radius > 0.0)) return;

  const double cx = centre.x(), cy = centre.y(), cz = centre.z();
  const double r2 = radius * radius;
  const double r3 = r2 * radius;
  const double ball_volume = kUnitBallVolume * r3;

  // Nothing to do unless the ball reaches into the patch's bounding box.
  {
    const double gx = gap(cx, x[0], x[sx]), gy = gap(cy, y[0], y[sy]), gz = gap(cz, z[0], z[sz]);
    if (gx * gx + (gy * gy + gz * gz) >= r2) return;
  }

  // Orthant volume of the unit ball at every node, in scaled coordinates.  Along each
  // axis the half-line below a node is  u * [unbounded] + s * [threshold t]  (see
  // below_terms), so the node value expands into the ball, caps depending on one axis,
  // corners with one unbounded axis depending on two axes (tabulated), and the full
  // corner K(tx, ty, tz).  Every distinct term is evaluated once.
  const std::size_t mx = sx + 1, my = sy + 1, mz = sz + 1;
  const std::size_t n_nodes = mx * my * mz;
  scratch.resize(n_nodes + mx * my + mx + 4 * (mx + my + mz) + 4 * (sx + sy + sz));
  double* node = scratch.data();
  double* pair_xy = node + n_nodes;     // W(tx_i, ty_j)
  double* pair_zx = pair_xy + mx * my;  // W(tx_i, tz_k), current k
  AxisNodes ax, ay, az;
  double* tables = pair_zx + mx;  // per-axis arrays, handed out in turn
  const bool any_ux = ax.setup(x, mx, cx, radius, tables);
  const bool any_uy = ay.setup(y, my, cy, radius, tables);
  const bool any_uz = az.setup(z, mz, cz, radius, tables);

  if (any_uz)
    for (std::size_t j = 0; j < my; ++j)
      for (std::size_t i = 0; i < mx; ++i)
        pair_xy[i + mx * j] = ax.s[i] != 0.0 && ay.s[j] != 0.0
                                  ? unit_ball_wedge(ax.t[i], ay.t[j])
                                  : 0.0;
  for (std::size_t k = 0; k < mz; ++k) {
    double* plane = node + mx * my * k;
    const double uz = az.u[k], s_z = az.s[k], tz = az.t[k], capz = az.cap[k];
    if (uz == 0.0 && s_z == 0.0) {  // node plane below the ball
      std::fill(plane, plane + mx * my, 0.0);
      continue;
    }
    if (any_uy)
      for (std::size_t i = 0; i < mx; ++i)
        pair_zx[i] = ax.s[i] != 0.0 && s_z != 0.0 ? unit_ball_wedge(ax.t[i], tz) : 0.0;
    for (std::size_t j = 0; j < my; ++j) {
      double* row = plane + mx * j;
      const double uy = ay.u[j], s_y = ay.s[j], ty = ay.t[j], capy = ay.cap[j];
      if (uy == 0.0 && s_y == 0.0) {
        std::fill(row, row + mx, 0.0);
        continue;
      }
      const double pair_yz =
          any_ux && s_y != 0.0 && s_z != 0.0 ? unit_ball_wedge(ty, tz) : 0.0;
      // Terms with the x axis unbounded, and the weights of the x-threshold terms.
      const double with_ux =
          uy * uz * kUnitBallVolume + s_y * uz * capy + s_z * uy * capz + s_y * s_z * pair_yz;
      const double w_cap = uy * uz, w_xy = s_y * uz, w_zx = s_z * uy, w_xyz = s_y * s_z;
      const double* pxy = pair_xy + mx * j;
      for (std::size_t i = 0; i < mx; ++i) {
        const double s_x = ax.s[i];
        double v = ax.u[i] * with_ux;
        if (s_x != 0.0) {
          double tx_terms = w_cap * ax.cap[i] + w_xy * pxy[i] + w_zx * pair_zx[i];
          if (w_xyz != 0.0) tx_terms += w_xyz * unit_ball_corner(ax.t[i], ty, tz);
          v += s_x * tx_terms;
        }
        row[i] = v;
      }
    }
  }

  // Cells: 8-corner differences, with the exact early answers.
  AxisCells cells_x, cells_y, cells_z;
  cells_x.setup(x, sx, cx, radius, tables);
  cells_y.setup(y, sy, cy, radius, tables);
  cells_z.setup(z, sz, cz, radius, tables);
  const std::size_t ox = 1, oy = mx, oz = mx * my;
  for (std::size_t k = 0; k < sz; ++k) {
    const double gz2 = cells_z.gap2[k];
    if (gz2 >= r2) continue;
    for (std::size_t j = 0; j < sy; ++j) {
      const double gyz = cells_y.gap2[j] + gz2;
      if (gyz >= r2) continue;
      const double fyz = cells_y.reach2[j] + cells_z.reach2[k];
      const double dyz = cells_y.width[j] * cells_z.width[k];
      const bool in_yz = cells_y.holds[j] != 0.0 && cells_z.holds[k] != 0.0;
      double* out = volumes_out.data() + sx * (j + sy * k);
      const double* n0 = node + oy * j + oz * k;
      for (std::size_t i = 0; i < sx; ++i) {
        if (cells_x.gap2[i] + gyz >= r2) continue;  // not reached (tangent included)
        const double cell_volume = cells_x.width[i] * dyz;
        if (!(cell_volume > 0.0)) continue;  // degenerate cell
        if (cells_x.reach2[i] + fyz <= r2) {       // all corners inside the ball
          out[i] = cell_volume;
          continue;
        }
        if (in_yz && cells_x.holds[i] != 0.0) {  // ball inside the cell
          out[i] = ball_volume;
          continue;
        }
        const double* n = n0 + i;
        const double v = ((n[ox + oy + oz] - n[oy + oz]) - (n[ox + oz] - n[oz])) -
                         ((n[ox + oy] - n[oy]) - (n[ox] - n[0]));
        out[i] = std::clamp(v * r3, 0.0, std::min(cell_volume, ball_volume));
      }
    }
  }
}

}  // namespace vfe::kernels

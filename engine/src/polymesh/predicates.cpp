// Exact orientation signs: Shewchuk's error-bound filter (Adaptive Precision Floating-Point
// Arithmetic and Fast Robust Geometric Predicates, 1997) and, when it cannot decide,
// exact evaluation with floating-point expansions (sums of non-overlapping doubles).
#include "polymesh/predicates.hpp"

#include <algorithm>
#include <cmath>

namespace vfe::geom {
namespace {

// Half an ulp of 1.0.
constexpr double kEps = 0x1p-53;
// Error bounds of the plain evaluations below (Shewchuk's ccwerrboundA and o3derrboundA),
// doubled as a margin for compilers that fuse multiply-adds in the filter.
constexpr double kOrient2dBound = 2.0 * (3.0 + 16.0 * kEps) * kEps;

/// x + y = a + b exactly, |y| <= ulp(x)/2.
inline void two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  const double bv = x - a;
  const double av = x - bv;
  y = (a - av) + (b - bv);
}

/// x + y = a + b exactly, given |a| >= |b| (or a == 0).
inline void fast_two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  y = b - (x - a);
}

/// x + y = a * b exactly (fma is exact by definition).
inline void two_product(double a, double b, double& x, double& y) {
  x = a * b;
  y = std::fma(a, b, -x);
}

/// A floating-point expansion: the exact value is the sum of its components, which are
/// non-overlapping and ordered by increasing magnitude, so the sign is that of the last.
struct Expansion {
  static constexpr int kCapacity = 256;
  double c[kCapacity];
  int n = 0;

  Expansion() = default;
  Expansion(const Expansion& o) : n(o.n) { std::copy(o.c, o.c + o.n, c); }
  Expansion& operator=(const Expansion& o) {
    n = o.n;
    std::copy(o.c, o.c + o.n, c);
    return *this;
  }

  void push(double v) { c[n++] = v; }
  int sign() const { return n == 0 ? 0 : (c[n - 1] > 0) - (c[n - 1] < 0); }
};

Expansion from_diff(double a, double b) {
  Expansion e;
  double x, y;
  two_sum(a, -b, x, y);
  if (y != 0) e.push(y);
  if (x != 0 || e.n == 0) e.push(x);
  return e;
}

/// h = e + b (Shewchuk's GROW-EXPANSION with zero elimination).
void grow(const Expansion& e, double b, Expansion& h) {
  double q = b;
  h.n = 0;
  for (int i = 0; i < e.n; ++i) {
    double qn, hh;
    two_sum(q, e.c[i], qn, hh);
    q = qn;
    if (hh != 0) h.push(hh);
  }
  if (q != 0 || h.n == 0) h.push(q);
}

/// e + f.
Expansion sum(const Expansion& e, const Expansion& f) {
  Expansion a = e, b;
  for (int j = 0; j < f.n; ++j) {
    grow(a, f.c[j], b);
    a = b;
  }
  return a;
}

Expansion negate(Expansion e) {
  for (int i = 0; i < e.n; ++i) e.c[i] = -e.c[i];
  return e;
}

/// h = e * b (Shewchuk's SCALE-EXPANSION with zero elimination).
Expansion scale(const Expansion& e, double b) {
  Expansion h;
  if (e.n == 0) {
    h.push(0.0);
    return h;
  }
  double q, hh;
  two_product(e.c[0], b, q, hh);
  if (hh != 0) h.push(hh);
  for (int i = 1; i < e.n; ++i) {
    double p1, p0, s;
    two_product(e.c[i], b, p1, p0);
    two_sum(q, p0, s, hh);
    if (hh != 0) h.push(hh);
    fast_two_sum(p1, s, q, hh);
    if (hh != 0) h.push(hh);
  }
  if (q != 0 || h.n == 0) h.push(q);
  return h;
}

/// e * f.
Expansion product(const Expansion& e, const Expansion& f) {
  Expansion acc;
  acc.push(0.0);
  for (int j = 0; j < f.n; ++j) acc = sum(acc, scale(e, f.c[j]));
  return acc;
}

/// Exact sign of (ax - cx)(by - cy) - (ay - cy)(bx - cx) = twice the signed area of the
/// triangle abc in the plane of the two given coordinates.
int orient2d_exact(double ax, double ay, double bx, double by, double cx, double cy) {
  const double left = (ax - cx) * (by - cy);
  const double right = (ay - cy) * (bx - cx);
  const double det = left - right;
  const double bound = kOrient2dBound * (std::fabs(left) + std::fabs(right));
  if (det > bound) return 1;
  if (-det > bound) return -1;
  const Expansion acx = from_diff(ax, cx), acy = from_diff(ay, cy);
  const Expansion bcx = from_diff(bx, cx), bcy = from_diff(by, cy);
  return sum(product(acx, bcy), negate(product(acy, bcx))).sign();
}

/// Exact sign of det[a - d, b - d, c - d] (Shewchuk's orient3d, the negative of ours).
int shewchuk_orient3d_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const double adx = a.x() - d.x(), bdx = b.x() - d.x(), cdx = c.x() - d.x();
  const double ady = a.y() - d.y(), bdy = b.y() - d.y(), cdy = c.y() - d.y();
  const double adz = a.z() - d.z(), bdz = b.z() - d.z(), cdz = c.z() - d.z();
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = (std::fabs(bdxcdy) + std::fabs(cdxbdy)) * std::fabs(adz) +
                           (std::fabs(cdxady) + std::fabs(adxcdy)) * std::fabs(bdz) +
                           (std::fabs(adxbdy) + std::fabs(bdxady)) * std::fabs(cdz);
  const double bound = detail::kOrient3dBound * permanent;
  if (det > bound) return 1;
  if (-det > bound) return -1;

  // Exact: the differences are two-component expansions, then products and sums.
  const Expansion eadx = from_diff(a.x(), d.x()), ebdx = from_diff(b.x(), d.x()),
                  ecdx = from_diff(c.x(), d.x());
  const Expansion eady = from_diff(a.y(), d.y()), ebdy = from_diff(b.y(), d.y()),
                  ecdy = from_diff(c.y(), d.y());
  const Expansion eadz = from_diff(a.z(), d.z()), ebdz = from_diff(b.z(), d.z()),
                  ecdz = from_diff(c.z(), d.z());
  const Expansion bc = sum(product(ebdx, ecdy), negate(product(ecdx, ebdy)));
  const Expansion ca = sum(product(ecdx, eady), negate(product(eadx, ecdy)));
  const Expansion ab = sum(product(eadx, ebdy), negate(product(ebdx, eady)));
  return sum(sum(product(bc, eadz), product(ca, ebdz)), product(ab, ecdz)).sign();
}

}  // namespace

int orient3d_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   const Eigen::Vector3d& d) {
  return -shewchuk_orient3d_exact(a, b, c, d);
}

int detail::orient3d_sos_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& d) {
  const int s = orient3d_exact(a, b, c, d);
  if (s != 0) return s;
  // d exactly in the plane: orient3d(a, b, c, d + e(1, e, e^2)) = e n.(1, e, e^2) with
  // n = (b - a) x (c - a); its sign is the first non-zero of n_x, n_y, n_z.
  if (const int nx = orient2d_exact(a.y(), a.z(), b.y(), b.z(), c.y(), c.z())) return nx;
  if (const int ny = orient2d_exact(a.z(), a.x(), b.z(), b.x(), c.z(), c.x())) return ny;
  return orient2d_exact(a.x(), a.y(), b.x(), b.y(), c.x(), c.y());
}

}  // namespace vfe::geom

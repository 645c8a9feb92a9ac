// Tests of the exact sphere/box overlap kernel against an independent numerical oracle.
//
// The oracle never uses the closed form: it integrates the chord length of the ball
// inside the box,
//
//     V = int dx int dy | [zlo, zhi] /\ [-s, s] |,   s = sqrt(1 - x^2 - y^2),
//
// in scaled coordinates (unit ball at the origin).  The inner integral substitutes
// y = R sin(theta), R = sqrt(1 - x^2), which turns the integrand into a piecewise
// trigonometric polynomial; it is split at the kinks (R cos(theta) = |zlo|, |zhi|) and
// each piece is integrated with Gauss-Legendre.  The outer integrand is analytic between
// the radii at which the y-z disk touches a side or passes through a corner of the y-z
// rectangle; the x axis is split there and each piece is integrated with tanh-sinh
// quadrature, which is insensitive to the algebraic singularities at the piece ends.
#include "vfe/kernels/sphere_box_overlap.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <iostream>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

namespace {

using Eigen::Vector3d;
using vfe::kernels::sphere_box_overlap;
using vfe::kernels::sphere_patch_overlaps;
using vfe::kernels::sphere_patch_overlaps_into;
using vfe::kernels::unit_ball_octants;
using vfe::kernels::unit_ball_orthant_volume;

constexpr double kPi = std::numbers::pi;
constexpr double kUnitBall = 4.0 * kPi / 3.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

double ball_volume(double r) { return kUnitBall * r * r * r; }

// ---------------------------------------------------------------------------------------
// Oracle
// ---------------------------------------------------------------------------------------

/// Gauss-Legendre nodes and weights on [-1, 1], by Newton iteration on P_n.
struct GaussLegendre {
  static constexpr int n = 24;
  std::array<double, n> x{}, w{};
  GaussLegendre() {
    for (int i = 0; i < n; ++i) {
      double t = std::cos(kPi * (i + 0.75) / (n + 0.5));
      double dp = 0.0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1.0, p1 = t;
        for (int k = 2; k <= n; ++k) {
          const double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        dp = n * (t * p1 - p0) / (t * t - 1.0);
        const double dt = p1 / dp;
        t -= dt;
        if (std::abs(dt) < 1e-16) break;
      }
      x[i] = t;
      w[i] = 2.0 / ((1.0 - t * t) * dp * dp);
    }
  }
};

const GaussLegendre& gauss_legendre() {
  static const GaussLegendre rule;
  return rule;
}

/// Area of the disk of radius R (centre origin) inside [yl, yh] x [zl, zh].
double oracle_slice(double R, double yl, double yh, double zl, double zh) {
  if (!(R > 0.0)) return 0.0;
  const double a = std::max(yl, -R), b = std::min(yh, R);
  if (!(a < b)) return 0.0;
  const double ta = std::asin(std::clamp(a / R, -1.0, 1.0));
  const double tb = std::asin(std::clamp(b / R, -1.0, 1.0));
  std::vector<double> cuts{ta, tb};
  for (double zb : {zl, zh}) {
    const double q = std::abs(zb);
    if (q < R) {
      const double t0 = std::acos(q / R);
      for (double t : {-t0, t0})
        if (t > ta && t < tb) cuts.push_back(t);
    }
  }
  std::sort(cuts.begin(), cuts.end());
  const GaussLegendre& gl = gauss_legendre();
  double sum = 0.0;
  for (std::size_t p = 0; p + 1 < cuts.size(); ++p) {
    const double mid = 0.5 * (cuts[p] + cuts[p + 1]), half = 0.5 * (cuts[p + 1] - cuts[p]);
    if (!(half > 0.0)) continue;
    double piece = 0.0;
    for (int i = 0; i < GaussLegendre::n; ++i) {
      const double c = std::cos(mid + half * gl.x[i]);
      const double s = R * c;
      const double len = std::min(zh, s) - std::max(zl, -s);
      if (len > 0.0) piece += gl.w[i] * len * s;
    }
    sum += half * piece;
  }
  return sum;
}

/// Tanh-sinh quadrature of f over [a, b] (f bounded).  The error roughly squares with
/// every halving of the step, so a relative change below 1e-9 between two levels leaves
/// the finer estimate accurate to rounding.
template <class F>
double tanh_sinh(F&& f, double a, double b) {
  const double half = 0.5 * (b - a);
  if (!(half > 0.0)) return 0.0;
  const double t_max = 3.5;
  // Node at parameter t: distance from the nearer end and weight, both accurate near ends.
  auto contribution = [&](double t) {
    const double u = 0.5 * kPi * std::sinh(t);
    const double e = std::exp(-2.0 * std::abs(u));
    const double dist = 2.0 * half * e / (1.0 + e);  // half * (1 - tanh|u|)
    const double ch = std::cosh(u);
    const double w = 0.5 * kPi * std::cosh(t) / (ch * ch);
    if (!(dist > 0.0)) return 0.0;
    const double xx = t < 0.0 ? a + dist : b - dist;
    return w * f(xx);
  };
  // Compensated (Neumaier) accumulation of all nodes.
  double sum = 0.0, carry = 0.0;
  auto add = [&](double v) {
    const double s = sum + v;
    carry += std::abs(sum) >= std::abs(v) ? (sum - s) + v : (v - s) + sum;
    sum = s;
  };
  double h = 0.5;
  add(contribution(0.0));
  for (int k = 1; k * h <= t_max; ++k) {
    add(contribution(k * h));
    add(contribution(-k * h));
  }
  double estimate = half * h * (sum + carry);
  for (int level = 1; level <= 9; ++level) {
    h *= 0.5;
    for (int k = 1; k * h <= t_max; k += 2) {
      add(contribution(k * h));
      add(contribution(-k * h));
    }
    const double next = half * h * (sum + carry);
    const double change = std::abs(next - estimate);
    estimate = next;
    if (level >= 2 && change <= 1e-9 * std::abs(next)) break;
  }
  return estimate;
}

/// Volume of the unit ball (centre origin) inside [l, h].
double oracle_unit(const std::array<double, 3>& l, const std::array<double, 3>& h) {
  const double xa = std::max(l[0], -1.0), xb = std::min(h[0], 1.0);
  if (!(xa < xb)) return 0.0;
  // Radii of the y-z disk at which the slice area stops being analytic.
  std::vector<double> t2;
  for (double yb : {l[1], h[1]}) t2.push_back(yb * yb);
  for (double zb : {l[2], h[2]}) t2.push_back(zb * zb);
  for (double yb : {l[1], h[1]})
    for (double zb : {l[2], h[2]}) t2.push_back(yb * yb + zb * zb);
  t2.push_back(0.0);
  std::vector<double> cuts{xa, xb};
  for (double q : t2) {
    if (!(q < 1.0)) continue;
    const double x0 = std::sqrt(1.0 - q);
    for (double xc : {-x0, x0})
      if (xc > xa && xc < xb) cuts.push_back(xc);
  }
  std::sort(cuts.begin(), cuts.end());
  auto slice = [&](double x) {
    const double R = std::sqrt(std::max(0.0, (1.0 - x) * (1.0 + x)));
    return oracle_slice(R, l[1], h[1], l[2], h[2]);
  };
  double sum = 0.0;
  for (std::size_t p = 0; p + 1 < cuts.size(); ++p) sum += tanh_sinh(slice, cuts[p], cuts[p + 1]);
  return sum;
}

double oracle_box(const Vector3d& c, double r, const Vector3d& lo, const Vector3d& hi) {
  std::array<double, 3> l{}, h{};
  for (int a = 0; a < 3; ++a) {
    l[a] = (lo[a] - c[a]) / r;
    h[a] = (hi[a] - c[a]) / r;
  }
  return oracle_unit(l, h) * r * r * r;
}

double oracle_orthant(double x, double y, double z) {
  return oracle_unit({-2.0, -2.0, -2.0}, {x, y, z});
}

/// Spherical cap of height h of a ball of radius r (textbook formula).
double cap_volume(double r, double h) { return kPi * h * h * (3.0 * r - h) / 3.0; }

// ---------------------------------------------------------------------------------------
// Oracle self-checks
// ---------------------------------------------------------------------------------------

TEST(SphereBoxOracle, ReproducesElementaryVolumes) {
  EXPECT_NEAR(oracle_unit({-2, -2, -2}, {2, 2, 2}), kUnitBall, 1e-15 * kUnitBall);
  EXPECT_NEAR(oracle_unit({0, 0, 0}, {2, 2, 2}), kUnitBall / 8, 1e-15 * kUnitBall);
  for (double t : {-0.9, -0.3, 0.0, 0.4, 0.95})
    EXPECT_NEAR(oracle_unit({t, -2, -2}, {2, 2, 2}), cap_volume(1.0, 1.0 - t), 1e-15 * kUnitBall);
  // Cube inscribed in the ball.
  const double s = 1.0 / std::sqrt(3.0);
  EXPECT_NEAR(oracle_unit({-s, -s, -s}, {s, s, s}), 8 * s * s * s, 1e-15 * kUnitBall);
}

// ---------------------------------------------------------------------------------------
// unit_ball_orthant_volume
// ---------------------------------------------------------------------------------------

TEST(UnitBallOrthant, KnownValues) {
  EXPECT_NEAR(unit_ball_orthant_volume(0, 0, 0), kPi / 6, 1e-16);
  EXPECT_EQ(unit_ball_orthant_volume(kInf, kInf, kInf), kUnitBall);
  EXPECT_EQ(unit_ball_orthant_volume(1, 1, 1), kUnitBall);
  EXPECT_EQ(unit_ball_orthant_volume(5, 1e300, 2), kUnitBall);
  EXPECT_EQ(unit_ball_orthant_volume(-kInf, 0.3, 0.2), 0.0);
  EXPECT_EQ(unit_ball_orthant_volume(-1, kInf, kInf), 0.0);
  EXPECT_EQ(unit_ball_orthant_volume(0.5, -1, 0.5), 0.0);
  EXPECT_EQ(unit_ball_orthant_volume(0.5, 0.2, -3), 0.0);
  EXPECT_NEAR(unit_ball_orthant_volume(kInf, 0, kInf), kUnitBall / 2, 1e-15);
  EXPECT_NEAR(unit_ball_orthant_volume(0, 0, kInf), kUnitBall / 4, 1e-15);
  // Slabs are caps.
  for (double t : {-1.0 + 1e-9, -0.75, -0.5, -1e-12, 0.0, 1e-12, 0.25, 0.6, 1.0 - 1e-9}) {
    const double below = kUnitBall - cap_volume(1.0, 1.0 - t);
    EXPECT_NEAR(unit_ball_orthant_volume(kInf, kInf, t), below, 1e-15 * kUnitBall) << t;
    EXPECT_NEAR(unit_ball_orthant_volume(t, kInf, kInf), below, 1e-15 * kUnitBall) << t;
    EXPECT_NEAR(unit_ball_orthant_volume(kInf, t, 7.0), below, 1e-15 * kUnitBall) << t;
    // Quarter of a cap: the half-space Z <= t with X <= 0, Y <= 0.
    EXPECT_NEAR(unit_ball_orthant_volume(0, 0, t), below / 4, 1e-15 * kUnitBall) << t;
  }
}

TEST(UnitBallOrthant, MatchesOracleOnSpecialValues) {
  const double s2 = std::sqrt(0.5), s3 = std::sqrt(1.0 / 3.0);
  const std::vector<double> values{-1.0,       -1.0 + 1e-7, -s2, -0.5, -s3,  -1e-10, 0.0,
                                   1e-10,      s3,          0.5, s2,   0.8,  1.0 - 1e-7, 1.0};
  double max_err = 0.0;
  for (double x : values)
    for (double y : values)
      for (double z : values) {
        if (!(x <= y && y <= z)) continue;  // symmetric in its arguments
        const double v = unit_ball_orthant_volume(x, y, z);
        const double ref = oracle_orthant(x, y, z);
        max_err = std::max(max_err, std::abs(v - ref));
        ASSERT_NEAR(v, ref, 1e-14 * kUnitBall) << x << ' ' << y << ' ' << z;
        EXPECT_NEAR(unit_ball_orthant_volume(z, x, y), v, 2e-15 * kUnitBall);
        EXPECT_NEAR(unit_ball_orthant_volume(y, z, x), v, 2e-15 * kUnitBall);
      }
  std::cout << "orthant, special values: max |error| / ball = " << max_err / kUnitBall << '\n';
}

TEST(UnitBallOrthant, MatchesOracleOnAndNearTheSphere) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> n01;
  double max_err = 0.0;
  for (int it = 0; it < 160; ++it) {
    double x, y, z;
    if (it % 2 == 0) {  // point on the sphere
      Vector3d p(n01(rng), n01(rng), n01(rng));
      p.normalize();
      x = p.x();
      y = p.y();
      z = p.z();
    } else {  // x^2 + y^2 = 1 with z free
      const double phi = kPi * u(rng);
      x = std::cos(phi);
      y = std::sin(phi);
      z = u(rng);
    }
    if (it % 4 == 1) std::swap(y, z);
    const double v = unit_ball_orthant_volume(x, y, z);
    const double ref = oracle_orthant(x, y, z);
    max_err = std::max(max_err, std::abs(v - ref));
    ASSERT_NEAR(v, ref, 1e-14 * kUnitBall) << x << ' ' << y << ' ' << z;
  }
  std::cout << "orthant, on the sphere: max |error| / ball = " << max_err / kUnitBall << '\n';
}

TEST(UnitBallOrthant, MatchesOracleOnRandomArguments) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  double max_err = 0.0;
  for (int it = 0; it < 1000; ++it) {
    const double x = u(rng), y = u(rng), z = u(rng);
    const double v = unit_ball_orthant_volume(x, y, z);
    const double ref = oracle_orthant(x, y, z);
    max_err = std::max(max_err, std::abs(v - ref));
    ASSERT_NEAR(v, ref, 1e-14 * kUnitBall) << x << ' ' << y << ' ' << z;
  }
  std::cout << "orthant, random: max |error| / ball = " << max_err / kUnitBall << '\n';
}

TEST(UnitBallOrthant, ReflectionIdentitiesHoldToRoundOff) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.1, 1.1);
  double max_err = 0.0;
  for (int it = 0; it < 20000; ++it) {
    const double x = u(rng), y = u(rng), z = u(rng);
    const double v = unit_ball_orthant_volume(x, y, z);
    ASSERT_GE(v, 0.0);
    ASSERT_LE(v, kUnitBall);
    // V(x, y, z) + V(-x, y, z) = V(inf, y, z).
    const double e1 = v + unit_ball_orthant_volume(-x, y, z) - unit_ball_orthant_volume(kInf, y, z);
    // The eight sign flips partition the ball.
    double all = 0.0;
    for (int s = 0; s < 8; ++s)
      all += unit_ball_orthant_volume(s & 1 ? -x : x, s & 2 ? -y : y, s & 4 ? -z : z);
    const double e2 = all - kUnitBall;
    // Monotone in each argument.
    ASSERT_LE(unit_ball_orthant_volume(x - 0.01, y, z), v + 1e-15);
    ASSERT_GE(unit_ball_orthant_volume(x, y + 0.01, z), v - 1e-15);
    max_err = std::max({max_err, std::abs(e1), std::abs(e2)});
  }
  EXPECT_LE(max_err, 2e-15 * kUnitBall);
  std::cout << "orthant identities: max |residual| / ball = " << max_err / kUnitBall << '\n';
}

TEST(UnitBallOrthant, TinyCornersAreAccurate) {
  // Corner point just inside the sphere: the orthant beyond it is a tiny region.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  double max_err = 0.0;
  for (int it = 0; it < 40; ++it) {
    Vector3d p(std::abs(n01(rng)), std::abs(n01(rng)), std::abs(n01(rng)));
    p.normalize();
    p *= 1.0 - std::pow(10.0, -2.0 - 0.25 * it);
    const double v = unit_ball_orthant_volume(-p.x(), -p.y(), -p.z());
    const double ref = oracle_orthant(-p.x(), -p.y(), -p.z());
    ASSERT_GE(v, 0.0);
    max_err = std::max(max_err, std::abs(v - ref));
    ASSERT_NEAR(v, ref, 1e-15 * kUnitBall) << p.transpose();
  }
  std::cout << "orthant, tiny corners: max |error| / ball = " << max_err / kUnitBall << '\n';
}

// ---------------------------------------------------------------------------------------
// sphere_box_overlap
// ---------------------------------------------------------------------------------------

TEST(SphereBoxOverlap, MatchesOracleOnRandomBoxes) {
  std::mt19937_64 rng(123456789);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto uniform = [&](double a, double b) { return a + (b - a) * u01(rng); };
  const int cases = 4000;
  int partial = 0;
  double max_rel = 0.0;
  for (int it = 0; it < cases; ++it) {
    const double r = std::pow(10.0, uniform(-1.0, 1.0));
    const Vector3d c(uniform(-3, 3), uniform(-3, 3), uniform(-3, 3));
    // Box size regime: much smaller than, comparable to, or much larger than the ball.
    const double lo_exp = std::array<double, 3>{-3.0, -0.5, 0.5}[it % 3];
    Vector3d size;
    const double iso = std::pow(10.0, uniform(lo_exp, lo_exp + 1.5));
    for (int a = 0; a < 3; ++a)
      size[a] = r * ((it / 3) % 2 == 0 ? iso : std::pow(10.0, uniform(-2.0, 2.0)));
    // A point near the ball placed at a random position inside the box.
    Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = c[a] + r * uniform(-1.1, 1.1);
    Vector3d lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = p[a] - size[a] * u01(rng);
      hi[a] = lo[a] + size[a];
    }
    const double v = sphere_box_overlap(c, r, lo, hi);
    const double ref = oracle_box(c, r, lo, hi);
    const double ball = ball_volume(r);
    const double box = (hi - lo).prod();
    if (v > 0.0 && v < std::min(ball, box) * (1 - 1e-12)) ++partial;
    const double rel = std::abs(v - ref) / ball;
    max_rel = std::max(max_rel, rel);
    ASSERT_LE(rel, 1e-13) << "c=" << c.transpose() << " r=" << r << " lo=" << lo.transpose()
                          << " hi=" << hi.transpose() << " v=" << v << " ref=" << ref;
    ASSERT_GE(v, 0.0);
    ASSERT_LE(v, std::min(ball, box) * (1.0 + 1e-15));
  }
  EXPECT_GT(partial, cases / 2);
  std::cout << "box, random: " << partial << " partial overlaps of " << cases
            << ", max |error| / ball = " << max_rel << '\n';
}

TEST(SphereBoxOverlap, TangentFromOutsideIsExactlyZero) {
  const Vector3d c(0.25, -1.5, 3.0);
  // Face: x-distance 2 = radius.
  EXPECT_EQ(sphere_box_overlap(c, 2.0, c + Vector3d(2, -1, -1), c + Vector3d(4, 1, 1)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 2.0, c + Vector3d(-1, -7, -1), c + Vector3d(1, -2, 1)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 2.0, c + Vector3d(-50, -50, 2), c + Vector3d(50, 50, 9)), 0.0);
  // Edge: distance sqrt(3^2 + 4^2) = 5 = radius.
  EXPECT_EQ(sphere_box_overlap(c, 5.0, c + Vector3d(3, 4, -1), c + Vector3d(6, 8, 1)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 5.0, c + Vector3d(-9, -9, -9), c + Vector3d(-3, 9, -4)), 0.0);
  // Corner: distance sqrt(2^2 + 3^2 + 6^2) = 7 = radius.
  EXPECT_EQ(sphere_box_overlap(c, 7.0, c + Vector3d(2, 3, 6), c + Vector3d(3, 4, 7)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 7.0, c - Vector3d(12, 13, 16), c - Vector3d(2, 3, 6)), 0.0);
  // Clearly apart.
  EXPECT_EQ(sphere_box_overlap(c, 1.0, c + Vector3d(0.8, 0.8, 0.8), c + Vector3d(2, 2, 2)), 0.0);
  // Just inside the tangent position: positive.
  EXPECT_GT(sphere_box_overlap(c, 2.0, c + Vector3d(2 - 1e-9, -1, -1), c + Vector3d(4, 1, 1)), 0.0);
}

TEST(SphereBoxOverlap, ContainmentGivesExactVolumes) {
  const Vector3d c(1.0, 2.0, -0.5);
  const double r = 0.75;
  EXPECT_DOUBLE_EQ(sphere_box_overlap(c, r, c - Vector3d(1, 2, 3), c + Vector3d(3, 2, 1)),
                   ball_volume(r));
  // Ball touching the box from inside.
  EXPECT_DOUBLE_EQ(sphere_box_overlap(c, r, c - Vector3d(r, r, r), c + Vector3d(r, 2, r)),
                   ball_volume(r));
  // Box inside the ball, including a box inscribed with its corners on the sphere
  // (edge lengths 2, 4, 4 with radius 3).
  const Vector3d lo = c + Vector3d(-0.3, -0.2, 0.1), hi = c + Vector3d(0.2, 0.25, 0.4);
  EXPECT_DOUBLE_EQ(sphere_box_overlap(c, r, lo, hi), (hi - lo).prod());
  const Vector3d o(0.0, 0.0, 0.0);
  EXPECT_DOUBLE_EQ(sphere_box_overlap(o, 3.0, Vector3d(-1, -2, -2), Vector3d(1, 2, 2)), 32.0);
}

TEST(SphereBoxOverlap, CentreOnFaceEdgeCorner) {
  const Vector3d c(0.5, -0.25, 2.0);
  const double r = 1.5, ball = ball_volume(r), tol = 4e-16 * ball;
  const double big = 10.0;
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(0, -big, -big), c + Vector3d(big, big, big)),
              ball / 2, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(-big, -big, -big), c + Vector3d(big, 0, big)),
              ball / 2, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(0, 0, -big), c + Vector3d(big, big, big)),
              ball / 4, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(-big, -big, -big), c + Vector3d(0, big, 0)),
              ball / 4, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c, c + Vector3d(big, big, big)), ball / 8, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c - Vector3d(big, big, big), c), ball / 8, tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(-big, 0, -big), c + Vector3d(0, big, 0)),
              ball / 8, tol);
  // Box face exactly on the sphere's extent: hemisphere / quarter with finite box.
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(0, -r, -r), c + Vector3d(r, r, r)), ball / 2,
              tol);
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(-r, 0, 0), c + Vector3d(r, r, r)), ball / 4,
              tol);
  // A slab through the centre of half-thickness t: ball minus two caps.
  const double t = 0.4;
  EXPECT_NEAR(sphere_box_overlap(c, r, c + Vector3d(-big, -t, -big), c + Vector3d(big, t, big)),
              ball - 2 * cap_volume(r, r - t), tol);
}

TEST(SphereBoxOverlap, TinyOverlapsMatchCapAndOracle) {
  // Coordinates chosen so that the face offsets below are formed without rounding.
  const Vector3d c(3.0, 3.25, 3.5);
  const double r = 2.0, ball = ball_volume(r);
  for (double rel_h : {1e-3, 1e-4, 1e-5, 1e-6, 1e-7}) {
    const double h = rel_h * r;
    const double cap = cap_volume(r, h);
    // Cap through a face of a large box, in each axis direction.
    for (int a = 0; a < 3; ++a) {
      Vector3d lo = c - Vector3d::Constant(5.0), hi = c + Vector3d::Constant(5.0);
      lo[a] = c[a] + r - h;
      const double v = sphere_box_overlap(c, r, lo, hi);
      EXPECT_NEAR(v, cap, 1e-15 * ball);
      EXPECT_NEAR(v, cap_volume(r, r - (lo[a] - c[a])), 1e-12 * cap) << rel_h;
      hi = c + Vector3d::Constant(5.0);
      lo = c - Vector3d::Constant(5.0);
      hi[a] = c[a] - r + h;
      EXPECT_NEAR(sphere_box_overlap(c, r, lo, hi), cap_volume(r, (hi[a] - c[a]) + r), 1e-12 * cap)
          << rel_h;
    }
    // Box corner poking into the ball by h (along the diagonal), and an edge.
    const double d = (r - h) / std::sqrt(3.0);
    // These are accurate in absolute terms (the region is O(h^3) resp. O(h^2.5) small).
    const Vector3d lo = c + Vector3d(d, d, d), hi = lo + Vector3d(1, 1, 1);
    const double v = sphere_box_overlap(c, r, lo, hi);
    EXPECT_GE(v, 0.0);
    if (rel_h >= 1e-4) {
      EXPECT_GT(v, 0.0);
    }
    EXPECT_NEAR(v, oracle_box(c, r, lo, hi), 1e-15 * ball) << rel_h;
    const double e = (r - h) / std::sqrt(2.0);
    const Vector3d elo = c + Vector3d(e, -0.3, e), ehi = elo + Vector3d(1, 1, 1);
    const double ve = sphere_box_overlap(c, r, elo, ehi);
    EXPECT_GE(ve, 0.0);
    if (rel_h >= 1e-4) {
      EXPECT_GT(ve, 0.0);
    }
    EXPECT_NEAR(ve, oracle_box(c, r, elo, ehi), 1e-15 * ball) << rel_h;
  }
}

TEST(SphereBoxOverlap, TranslationAndScaleConsistency) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int it = 0; it < 2000; ++it) {
    const Vector3d c(u(rng), u(rng), u(rng));
    const double r = 1.0 + 0.5 * u(rng);
    Vector3d lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    for (int a = 0; a < 3; ++a)
      if (lo[a] > hi[a]) std::swap(lo[a], hi[a]);
    const double v = sphere_box_overlap(c, r, lo, hi);
    const Vector3d shift(0.375, -1.25, 2.5);
    EXPECT_NEAR(sphere_box_overlap(c + shift, r, lo + shift, hi + shift), v,
                1e-14 * ball_volume(r));
    // Scaling by a power of two changes nothing but the exponent.
    EXPECT_DOUBLE_EQ(sphere_box_overlap(4.0 * c, 4.0 * r, 4.0 * lo, 4.0 * hi), 64.0 * v);
    // Mirror symmetry.
    EXPECT_NEAR(sphere_box_overlap(-c, r, -hi, -lo), v, 2e-15 * ball_volume(r));
  }
}

TEST(SphereBoxOverlap, DegenerateInputsGiveZero) {
  const Vector3d c(0, 0, 0), lo(-1, -1, -1), hi(1, 1, 1);
  EXPECT_EQ(sphere_box_overlap(c, 0.0, lo, hi), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, -1.0, lo, hi), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 0.5, Vector3d(-1, 0.1, -1), Vector3d(1, 0.1, 1)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 0.5, Vector3d(0, 0, 0), Vector3d(0, 0, 0)), 0.0);
  EXPECT_EQ(sphere_box_overlap(c, 0.5, hi, lo), 0.0);
}

// ---------------------------------------------------------------------------------------
// sphere_patch_overlaps_into
// ---------------------------------------------------------------------------------------

TEST(SpherePatchOverlaps, MatchesPerCellOverlapsOnRandomPatches) {
  std::mt19937_64 rng(4242);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_int_distribution<int> ncells(1, 6);
  std::vector<double> scratch, volumes;
  double max_cell = 0.0, max_sum = 0.0;
  for (int it = 0; it < 2000; ++it) {
    const double r = 0.2 + 2.0 * u01(rng);
    const Vector3d c(u01(rng), u01(rng), u01(rng));
    const int n[3] = {ncells(rng), ncells(rng), ncells(rng)};
    std::vector<double> nodes[3];
    for (int a = 0; a < 3; ++a) {
      // Non-uniform spacing; the patch roughly covers the ball, sometimes only part of it.
      const double spacing = (0.2 + 1.5 * u01(rng)) * r;
      double t = c[a] - r * (1.2 * u01(rng) + (it % 5 == 0 ? -0.5 : 0.3));
      for (int i = 0; i <= n[a]; ++i) {
        nodes[a].push_back(t);
        t += spacing * (0.5 + u01(rng));
      }
    }
    if (it % 7 == 0 && n[0] >= 2 && nodes[0][0] < c.x() && c.x() < nodes[0][2])
      nodes[0][1] = c.x();  // a node plane through the centre
    sphere_patch_overlaps_into(c, r, nodes[0].data(), n[0], nodes[1].data(), n[1],
                               nodes[2].data(), n[2], scratch, volumes);
    ASSERT_EQ(volumes.size(), static_cast<std::size_t>(n[0] * n[1] * n[2]));
    const double ball = ball_volume(r);
    double sum = 0.0;
    for (int k = 0; k < n[2]; ++k)
      for (int j = 0; j < n[1]; ++j)
        for (int i = 0; i < n[0]; ++i) {
          const Vector3d lo(nodes[0][i], nodes[1][j], nodes[2][k]);
          const Vector3d hi(nodes[0][i + 1], nodes[1][j + 1], nodes[2][k + 1]);
          const double v = volumes[static_cast<std::size_t>(i + n[0] * (j + n[1] * k))];
          const double ref = sphere_box_overlap(c, r, lo, hi);
          max_cell = std::max(max_cell, std::abs(v - ref) / ball);
          ASSERT_NEAR(v, ref, 1e-13 * ball) << i << ' ' << j << ' ' << k;
          ASSERT_GE(v, 0.0);
          ASSERT_LE(v, (hi - lo).prod() * (1.0 + 1e-15));
          // Exact zeros and exact full cells.
          const Vector3d gap = (lo - c).cwiseMax(c - hi).cwiseMax(0.0);
          if (gap.squaredNorm() >= r * r) {
            ASSERT_EQ(v, 0.0);
          }
          const Vector3d far = (c - lo).cwiseMax(hi - c);
          if (far.squaredNorm() <= r * r) {
            ASSERT_DOUBLE_EQ(v, (hi - lo).prod());
          }
          sum += v;
        }
    const Vector3d plo(nodes[0].front(), nodes[1].front(), nodes[2].front());
    const Vector3d phi(nodes[0].back(), nodes[1].back(), nodes[2].back());
    const double whole = sphere_box_overlap(c, r, plo, phi);
    max_sum = std::max(max_sum, std::abs(sum - whole) / ball);
    ASSERT_NEAR(sum, whole, 1e-13 * ball);
  }
  std::cout << "patch: max |cell - box| / ball = " << max_cell
            << ", max |sum - bounding box| / ball = " << max_sum << '\n';
}

TEST(SpherePatchOverlaps, CellsOutsideTheBallAreExactlyZero) {
  // Unit spacing grid, ball of diameter 1 centred in cell (2, 2, 2) of a 5^3 patch, and a
  // ball tangent to the node plane x = 2 from below.
  std::vector<double> g{0, 1, 2, 3, 4, 5};
  std::vector<double> scratch, volumes;
  sphere_patch_overlaps_into(Vector3d(2.5, 2.5, 2.5), 0.5, g.data(), 5, g.data(), 5, g.data(), 5,
                             scratch, volumes);
  ASSERT_EQ(volumes.size(), 125u);
  for (std::size_t n = 0; n < volumes.size(); ++n) {
    if (n == 2 + 5 * (2 + 5 * 2))
      EXPECT_DOUBLE_EQ(volumes[n], ball_volume(0.5));
    else
      EXPECT_EQ(volumes[n], 0.0) << n;
  }
  sphere_patch_overlaps_into(Vector3d(1.25, 2.5, 2.5), 0.75, g.data(), 5, g.data(), 5, g.data(), 5,
                             scratch, volumes);
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 2; i < 5; ++i) EXPECT_EQ(volumes[i + 5 * (j + 5 * k)], 0.0);
  double sum = 0.0;
  for (double v : volumes) sum += v;
  EXPECT_NEAR(sum, ball_volume(0.75), 1e-15 * ball_volume(0.75));
  // A ball entirely outside the patch.
  sphere_patch_overlaps_into(Vector3d(-1.0, 2.5, 2.5), 1.0, g.data(), 5, g.data(), 5, g.data(), 5,
                             scratch, volumes);
  for (double v : volumes) EXPECT_EQ(v, 0.0);
}

TEST(SpherePatchOverlaps, ReusesBuffersAndFeedsTheSink) {
  std::vector<double> gx{-1.0, -0.4, 0.3, 1.0}, gy{-0.9, 0.1, 0.8}, gz{-1.2, -0.2, 0.5, 1.1};
  std::vector<double> scratch, volumes;
  const Vector3d c(0.05, -0.1, 0.02);
  sphere_patch_overlaps_into(c, 0.7, gx.data(), 3, gy.data(), 2, gz.data(), 3, scratch, volumes);
  const double* scratch_data = scratch.data();
  const double* volume_data = volumes.data();
  const std::vector<double> first = volumes;
  sphere_patch_overlaps_into(c, 0.7, gx.data(), 3, gy.data(), 2, gz.data(), 3, scratch, volumes);
  EXPECT_EQ(scratch.data(), scratch_data);
  EXPECT_EQ(volumes.data(), volume_data);
  EXPECT_EQ(volumes, first);

  double total = 0.0;
  int calls = 0, last = -1;
  sphere_patch_overlaps(c, 0.7, gx.data(), 3, gy.data(), 2, gz.data(), 3, scratch, volumes,
                        [&](int i, int j, int k, double v) {
                          const int index = i + 3 * (j + 2 * k);
                          EXPECT_GT(index, last);
                          EXPECT_GT(v, 0.0);
                          last = index;
                          total += v;
                          ++calls;
                        });
  EXPECT_EQ(calls, 18);
  EXPECT_NEAR(total, ball_volume(0.7), 1e-15 * ball_volume(0.7));
}


// ---------------------------------------------------------------------------------------
// unit_ball_octants
// ---------------------------------------------------------------------------------------

/// The oracle's volume of part m of unit_ball_octants(a, b, c): the unit ball in the box
/// on the upper side of plane t[d] where bit d of m is set, on the lower side otherwise.
double oracle_octant(const std::array<double, 3>& t, unsigned m) {
  std::array<double, 3> l{}, h{};
  for (int d = 0; d < 3; ++d) {
    const double at = std::clamp(t[d], -2.0, 2.0);
    l[d] = (m >> d) & 1u ? at : -2.0;
    h[d] = (m >> d) & 1u ? 2.0 : at;
  }
  return oracle_unit(l, h);
}

/// unit_ball_octants(t) against the oracle, part by part; returns the largest error / ball.
double octants_error(const std::array<double, 3>& t) {
  double parts[8];
  unit_ball_octants(t[0], t[1], t[2], parts);
  double worst = 0.0, sum = 0.0;
  for (unsigned m = 0; m < 8; ++m) {
    EXPECT_GE(parts[m], 0.0);
    worst = std::max(worst, std::abs(parts[m] - oracle_octant(t, m)) / kUnitBall);
    sum += parts[m];
  }
  EXPECT_NEAR(sum, kUnitBall, 2e-15 * kUnitBall) << t[0] << ' ' << t[1] << ' ' << t[2];
  return worst;
}

TEST(UnitBallOctants, MatchesOracleOnRandomPlanes) {
  std::mt19937_64 rng(20261202);
  std::uniform_real_distribution<double> u(-1.15, 1.15);  // some planes miss the ball
  double max_err = 0.0;
  for (int it = 0; it < 250; ++it) {
    const double err = octants_error({u(rng), u(rng), u(rng)});
    max_err = std::max(max_err, err);
    ASSERT_LE(err, 1e-14) << it;
  }
  std::cout << "octants, random: max |error| / ball = " << max_err << '\n';
}

TEST(UnitBallOctants, MatchesOracleOnSpecialPlanes) {
  // Planes through the centre, 1e-10 from it, at the corners of inscribed cubes and
  // squares, within 1e-7 of the surface, tangent and beyond it.
  const double s2 = std::sqrt(0.5), s3 = std::sqrt(1.0 / 3.0);
  const std::vector<double> values{-kInf, -1.0, -1.0 + 1e-7, -s2, -s3, -1e-10, 0.0, -0.0,
                                   1e-10, 0.5,  s3,          s2,  0.8, 1.0 - 1e-7, 1.0, 3.0};
  double max_err = 0.0;
  for (double a : values)
    for (double b : values)
      for (double c : values) {
        if (!(std::abs(a) <= std::abs(b) && std::abs(b) <= std::abs(c))) continue;  // the rest by symmetry
        const double err = octants_error({a, b, c});
        max_err = std::max(max_err, err);
        ASSERT_LE(err, 1e-14) << a << ' ' << b << ' ' << c;
      }
  std::cout << "octants, special planes: max |error| / ball = " << max_err << '\n';
}

TEST(UnitBallOctants, NodesOnAndNearTheSphere) {
  // The node where the three planes meet on the sphere (the corner part vanishes), just
  // inside it (a tiny corner), and two planes meeting on it.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  double max_err = 0.0;
  for (int it = 0; it < 60; ++it) {
    Vector3d p(n01(rng), n01(rng), n01(rng));
    p.normalize();
    if (it % 3 == 1) p *= 1.0 - std::pow(10.0, -3.0 - 0.2 * it);
    if (it % 3 == 2) {
      p.z() = 0.3 * n01(rng);
      p.head<2>() *= std::sqrt(1.0 - std::min(p.z() * p.z(), 1.0)) / p.head<2>().norm();
    }
    const double err = octants_error({p.x(), p.y(), p.z()});
    max_err = std::max(max_err, err);
    ASSERT_LE(err, 1e-15 * 4) << p.transpose();
  }
  std::cout << "octants, nodes on the sphere: max |error| / ball = " << max_err << '\n';
}

TEST(UnitBallOctants, PlanesMissingTheBallLeaveExactZerosAndCaps) {
  double parts[8];
  // No plane cuts: the whole ball on the near side of each, exactly.
  unit_ball_octants(kInf, 1.0, -kInf, parts);
  for (unsigned m = 0; m < 8; ++m) EXPECT_EQ(parts[m], m == 4 ? kUnitBall : 0.0) << m;
  unit_ball_octants(std::nan(""), 5.0, 1e300, parts);
  for (unsigned m = 1; m < 8; ++m) EXPECT_EQ(parts[m] * parts[0], 0.0) << m;  // one part holds the ball
  // One plane cuts: the parts are the cap and the rest, to the cap formula's relative
  // accuracy however thin the cap (planes within 1e-12 of the surface included).
  for (double t : {0.0, 0.3, 0.9, 1.0 - 1e-6, 1.0 - 1e-9, 1.0 - 1e-12, 1.0 - 0x1p-52}) {
    for (int axis = 0; axis < 3; ++axis)
      for (double sign : {1.0, -1.0}) {
        double plane[3] = {kInf, -kInf, 2.0};
        plane[axis] = sign * t;
        unit_ball_octants(plane[0], plane[1], plane[2], parts);
        const unsigned base = axis == 1 ? 0u : 2u;  // a Y plane at -inf: everything on its upper side
        const unsigned far = base | (sign > 0 ? 1u << axis : 0u), near = far ^ (1u << axis);
        const double cap = cap_volume(1.0, 1.0 - t);
        EXPECT_NEAR(parts[far], cap, 1e-14 * cap) << t << ' ' << axis;
        EXPECT_NEAR(parts[near], kUnitBall - cap, 1e-15 * kUnitBall) << t << ' ' << axis;
        for (unsigned m = 0; m < 8; ++m) {
          if (m != far && m != near) {
            EXPECT_EQ(parts[m], 0.0);
          }
        }
      }
  }
  // Tangent: a plane at exactly +-1 leaves its far side exactly 0.
  unit_ball_octants(1.0, -1.0, 0.25, parts);
  for (unsigned m = 0; m < 8; ++m) {
    if ((m & 1) || !(m & 2)) {
      EXPECT_EQ(parts[m], 0.0) << m;
    }
  }
}

TEST(UnitBallOctants, ThinCapsCutByASecondPlaneStayAccurateAgainstTheBall) {
  // A plane 1e-4 .. 1e-12 below the surface with a second plane through the cap: the
  // two halves come from a cap less a wedge, accurate to round-off of the ball (their
  // relative accuracy is that of the wedge's closed form, not the cap's).
  for (double h : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12}) {
    for (double b : {0.0, 0.3 * std::sqrt(h)}) {
      double parts[8];
      unit_ball_octants(1.0 - h, b, kInf, parts);
      const double cap = cap_volume(1.0, h);
      EXPECT_NEAR(parts[1] + parts[3], cap, 1e-15 * kUnitBall) << h;
      EXPECT_NEAR(parts[1], oracle_octant({1.0 - h, b, kInf}, 1), 1e-15 * kUnitBall) << h << ' ' << b;
      EXPECT_NEAR(parts[3], oracle_octant({1.0 - h, b, kInf}, 3), 1e-15 * kUnitBall) << h << ' ' << b;
      if (b == 0.0) {
        EXPECT_NEAR(parts[1], parts[3], 1e-15 * kUnitBall);
      }
    }
  }
}

TEST(UnitBallOctants, AgreesWithBoxOverlapsAndReflections) {
  // Each part is the overlap of the unit ball with its (large) box; mirroring a plane
  // swaps the parts on its two sides.
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(-1.05, 1.05);
  double max_err = 0.0;
  for (int it = 0; it < 5000; ++it) {
    const double t[3] = {u(rng), u(rng), u(rng)};
    double parts[8], mirrored[8];
    unit_ball_octants(t[0], t[1], t[2], parts);
    unit_ball_octants(-t[0], t[1], -t[2], mirrored);
    for (unsigned m = 0; m < 8; ++m) {
      Vector3d lo, hi;
      for (int d = 0; d < 3; ++d) {
        lo[d] = (m >> d) & 1u ? t[d] : -4.0;
        hi[d] = (m >> d) & 1u ? 4.0 : t[d];
      }
      const double box = sphere_box_overlap(Vector3d::Zero(), 1.0, lo, hi);
      max_err = std::max(max_err, std::abs(parts[m] - box));
      ASSERT_NEAR(parts[m], box, 2e-15 * kUnitBall) << it << ' ' << m;
      ASSERT_EQ(parts[m], mirrored[m ^ 5u]) << it << ' ' << m;
      if (box == 0.0) {
        ASSERT_EQ(parts[m], 0.0);
      }
    }
  }
  std::cout << "octants vs box overlaps: max |difference| / ball = " << max_err / kUnitBall << '\n';
}

}  // namespace

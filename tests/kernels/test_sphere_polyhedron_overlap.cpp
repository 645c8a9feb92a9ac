// Tests of the exact sphere/polyhedron overlap kernel against independent oracles:
//  - boxes (as 6 quads and as 12 triangles) against the closed form of sphere_box_overlap;
//  - tetrahedra and non-box hexahedra against numerical integration of the chord length:
//        V = int dz int dy | [x0, x1] /\ [cx - w, cx + w] |,   w = sqrt(R^2 - (y-cy)^2 - (z-cz)^2),
//    [x0, x1] being the convex polyhedron's chord cut by its face half-spaces; both
//    integrals split where the integrand is not analytic and integrated piecewise by
//    tanh-sinh quadrature (see integrated_overlap; agreement to 1e-12 of the ball volume
//    is asserted);
//  - degenerate placements with known answers, and additivity over decompositions.
#include "vfe/kernels/sphere_box_overlap.hpp"
#include "vfe/kernels/sphere_polyhedron_overlap.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using vfe::kernels::sphere_box_overlap;
using vfe::kernels::sphere_polyhedron_overlap;
using vfe::kernels::sphere_tetrahedron_overlap;

constexpr double kPi = std::numbers::pi;

double ball_volume(double r) { return 4.0 / 3.0 * kPi * (r * r * r); }

/// A polyhedron as the kernel takes it.
struct Polyhedron {
  std::vector<Vector3d> vertices;
  std::vector<std::int32_t> offsets{0}, indices;

  void face(std::initializer_list<std::int32_t> ids) {
    indices.insert(indices.end(), ids.begin(), ids.end());
    offsets.push_back(static_cast<std::int32_t>(indices.size()));
  }
  double overlap(const Vector3d& c, double r) const { return sphere_polyhedron_overlap(c, r, vertices, offsets, indices); }
  /// Volume by the divergence theorem (fan of each face about its first vertex).
  double volume() const {
    double v = 0;
    for (std::size_t f = 0; f + 1 < offsets.size(); ++f)
      for (std::int32_t k = offsets[f] + 1; k + 1 < offsets[f + 1]; ++k)
        v += vertices[indices[offsets[f]]].dot(vertices[indices[k]].cross(vertices[indices[k + 1]])) / 6;
    return v;
  }
};

/// Hexahedron with bottom 0-3 (counter-clockwise seen from above) and top 4-7 above them.
Polyhedron hexahedron(const std::array<Vector3d, 8>& p) {
  Polyhedron h;
  h.vertices.assign(p.begin(), p.end());
  h.face({0, 3, 2, 1});
  h.face({4, 5, 6, 7});
  h.face({0, 1, 5, 4});
  h.face({1, 2, 6, 5});
  h.face({2, 3, 7, 6});
  h.face({3, 0, 4, 7});
  return h;
}

std::array<Vector3d, 8> box_corners(const Vector3d& lo, const Vector3d& hi) {
  return {Vector3d(lo.x(), lo.y(), lo.z()), Vector3d(hi.x(), lo.y(), lo.z()), Vector3d(hi.x(), hi.y(), lo.z()),
          Vector3d(lo.x(), hi.y(), lo.z()), Vector3d(lo.x(), lo.y(), hi.z()), Vector3d(hi.x(), lo.y(), hi.z()),
          Vector3d(hi.x(), hi.y(), hi.z()), Vector3d(lo.x(), hi.y(), hi.z())};
}

/// The hexahedron's quads as 12 triangles, each quad split along the diagonal `diagonal` picks.
Polyhedron triangulated(const Polyhedron& quads, std::mt19937_64& rng) {
  Polyhedron t;
  t.vertices = quads.vertices;
  for (std::size_t f = 0; f + 1 < quads.offsets.size(); ++f) {
    const std::int32_t* q = &quads.indices[quads.offsets[f]];
    if (rng() & 1) {
      t.face({q[0], q[1], q[2]});
      t.face({q[0], q[2], q[3]});
    } else {
      t.face({q[0], q[1], q[3]});
      t.face({q[1], q[2], q[3]});
    }
  }
  return t;
}

// ---------------------------------------------------------------------------------------
// Numerical oracle

/// Tanh-sinh quadrature of f on [a, b]: exponentially convergent for a function analytic
/// inside the interval, whatever its algebraic behaviour at the ends (step 1/8, |t| <= 3.25).
template <class F>
double tanh_sinh(const F& f, double a, double b) {
  if (!(b > a)) return 0;
  constexpr double step = 1.0 / 8;
  constexpr int n = 26;
  const double half = 0.5 * (b - a);
  double sum = 0;
  for (int k = -n; k <= n; ++k) {
    const double t = k * step, u = 0.5 * kPi * std::sinh(t);
    const double weight = 0.5 * kPi * std::cosh(t) / (std::cosh(u) * std::cosh(u));
    const double gap = half * 2 / (std::exp(2 * std::fabs(u)) + 1);  // distance to the nearer end
    sum += weight * f(k < 0 ? a + gap : (k > 0 ? b - gap : a + half));
  }
  return sum * half * step;
}

/// Sum of tanh_sinh over the pieces of [a, b] cut at the points `cuts` (any order, any place).
template <class F>
double piecewise(const F& f, double a, double b, std::vector<double>& cuts) {
  cuts.push_back(a);
  cuts.push_back(b);
  std::sort(cuts.begin(), cuts.end());
  double sum = 0, from = a;
  for (const double x : cuts) {
    if (x <= from) continue;
    if (x > b) break;
    sum += tanh_sinh(f, from, x);
    from = x;
  }
  return sum;
}

/// Real roots of a t^2 + b t + c = 0 (a > 0) appended to out.
void quadratic_roots(double a, double b, double c, std::vector<double>& out) {
  const double disc = b * b - 4 * a * c;
  if (disc < 0) return;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  if (q != 0) out.push_back(c / q);
  out.push_back(q / a);
}

/// |B(c, r) n P| for a convex polyhedron P, by quadrature over z then y of the length of the
/// chord in x (P's face half-spaces clip the ball's chord). The substitutions
/// z = cz + r sin(psi) and y = cy + rho sin(theta), rho = sqrt(r^2 - (z - cz)^2), remove the
/// square-root ends of the ball's chords; both integrals are split where the integrand is
/// not analytic (in y: where two face lines or a face line and the circle cross; in z: at
/// the vertices, where the edges cross the sphere and at the top and bottom of each face
/// plane's circle), and each piece is integrated by tanh-sinh.
double integrated_overlap(const Polyhedron& p, const Vector3d& c, double r) {
  std::vector<Vector3d> normals;
  std::vector<double> offsets;  // face k: normals[k] . x <= offsets[k]
  Vector3d lo = p.vertices[0], hi = p.vertices[0];
  for (const Vector3d& v : p.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  std::vector<double> z_cuts;
  for (const Vector3d& v : p.vertices) z_cuts.push_back(v.z());
  for (std::size_t f = 0; f + 1 < p.offsets.size(); ++f) {
    const std::int32_t b = p.offsets[f], e = p.offsets[f + 1];
    const Vector3d& v0 = p.vertices[p.indices[b]];
    const Vector3d n = (p.vertices[p.indices[b + 1]] - v0).cross(p.vertices[p.indices[b + 2]] - v0).normalized();
    normals.push_back(n);
    offsets.push_back(n.dot(v0));
    const double depth = n.dot(c) - offsets.back(), a2 = r * r - depth * depth;
    if (a2 > 0) {  // the circle the face plane cuts from the sphere: its lowest and highest z
      const double centre_z = c.z() - depth * n.z(), spread = std::sqrt(a2 * (1 - n.z() * n.z()));
      z_cuts.insert(z_cuts.end(), {centre_z - spread, centre_z + spread});
    }
    for (std::int32_t k = b; k < e; ++k) {  // where the edges cross the sphere
      const Vector3d& a = p.vertices[p.indices[k]];
      const Vector3d d = p.vertices[p.indices[k + 1 == e ? b : k + 1]] - a;
      std::vector<double> t;
      quadratic_roots(d.squaredNorm(), 2 * d.dot(a - c), (a - c).squaredNorm() - r * r, t);
      for (const double s : t)
        if (s >= 0 && s <= 1) z_cuts.push_back(a.z() + s * d.z());
    }
  }
  const auto angle = [](double x, double centre, double radius) {
    return std::asin(std::clamp((x - centre) / radius, -1.0, 1.0));
  };
  std::vector<double> psi_cuts, theta_cuts, y_cuts;
  for (const double z : z_cuts) psi_cuts.push_back(angle(z, c.z(), r));

  const auto slice = [&](double psi) {  // area of the z-slice times dz / dpsi
    const double z = c.z() + r * std::sin(psi), rho = r * std::cos(psi);
    if (!(rho > 0)) return 0.0;
    // Face k in this slice: x = line_p[k] + line_q[k] y, or a bound on y alone.
    std::vector<double> line_p, line_q;
    y_cuts.clear();
    for (std::size_t k = 0; k < normals.size(); ++k) {
      const Vector3d& n = normals[k];
      const double beta = offsets[k] - n.z() * z;
      if (n.x() != 0) {
        line_p.push_back(beta / n.x());
        line_q.push_back(-n.y() / n.x());
        const double e = line_p.back() - c.x(), q = line_q.back();
        quadratic_roots(q * q + 1, 2 * (e * q - c.y()), e * e + c.y() * c.y() - rho * rho, y_cuts);
      }
      if (std::fabs(n.x()) < 1e-9 && n.y() != 0) y_cuts.push_back(beta / n.y());  // (nearly) a bound on y
    }
    for (std::size_t i = 0; i < line_p.size(); ++i)
      for (std::size_t j = 0; j < i; ++j)
        if (line_q[i] != line_q[j]) y_cuts.push_back((line_p[j] - line_p[i]) / (line_q[i] - line_q[j]));
    theta_cuts.clear();
    for (const double y : y_cuts) theta_cuts.push_back(angle(y, c.y(), rho));
    const auto chord = [&](double theta) {
      const double y = c.y() + rho * std::sin(theta), w = rho * std::cos(theta);
      double x0 = c.x() - w, x1 = c.x() + w;
      for (std::size_t k = 0; k < normals.size(); ++k) {
        const double rhs = offsets[k] - normals[k].y() * y - normals[k].z() * z, nx = normals[k].x();
        if (nx > 0)
          x1 = std::min(x1, rhs / nx);
        else if (nx < 0)
          x0 = std::max(x0, rhs / nx);
        else if (rhs < 0)
          return 0.0;
      }
      return std::max(0.0, x1 - x0) * w;
    };
    return piecewise(chord, angle(lo.y(), c.y(), rho), angle(hi.y(), c.y(), rho), theta_cuts) * rho;
  };
  return piecewise(slice, angle(lo.z(), c.z(), r), angle(hi.z(), c.z(), r), psi_cuts);
}

Polyhedron tetrahedron(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  Polyhedron t;
  t.vertices = {a, b, c, d};
  if ((b - a).cross(c - a).dot(d - a) > 0) {
    t.face({0, 2, 1});
    t.face({0, 1, 3});
    t.face({0, 3, 2});
    t.face({1, 2, 3});
  } else {
    t.face({0, 1, 2});
    t.face({0, 3, 1});
    t.face({0, 2, 3});
    t.face({1, 3, 2});
  }
  return t;
}

/// A convex hexahedron with plane faces: rectangle [0, 1]^2 at z = 0 below the rectangle
/// [x0, x1] x [y0, y1] at z = 1 (opposite side edges are parallel), cut at z = t (from
/// z0 to z1 of the frustum), then mapped by x -> m x + shift.
std::array<Vector3d, 8> frustum(double x0, double x1, double y0, double y1, double z0, double z1, const Matrix3d& m,
                                const Vector3d& shift) {
  const auto at = [&](double z, int corner) {
    const double lx = (1 - z) * 0 + z * x0, hx = (1 - z) * 1 + z * x1;
    const double ly = (1 - z) * 0 + z * y0, hy = (1 - z) * 1 + z * y1;
    const double x = corner == 0 || corner == 3 ? lx : hx, y = corner < 2 ? ly : hy;
    return Vector3d(m * Vector3d(x, y, z) + shift);
  };
  return {at(z0, 0), at(z0, 1), at(z0, 2), at(z0, 3), at(z1, 0), at(z1, 1), at(z1, 2), at(z1, 3)};
}

/// A random map with determinant > 0 (rotation-ish times shear and scale).
Matrix3d random_map(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  Matrix3d m = Matrix3d::Identity();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) += u(rng);
  if (m.determinant() < 0) m.col(0) *= -1;
  return m;
}

/// The box [0, 2] x [0, 1] x [0, 1] split at x ~ 1 by a warped quad into two cells: the
/// quad's points, its apex (their mean) and the left cell (x = 0 side), the quad as the fan
/// of four triangles about the apex (as the engine gives it), oriented outwards.
struct WarpedSplit {
  std::array<Vector3d, 4> quad{Vector3d(1, 0, 0), Vector3d(1, 1, 0), Vector3d(1.2, 1, 1), Vector3d(0.9, 0, 1)};
  Vector3d apex = (quad[0] + quad[1] + quad[2] + quad[3]) / 4;
  Polyhedron left;

  WarpedSplit() {
    left.vertices = {{0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}, quad[0], quad[1], quad[2], quad[3], apex};
    left.face({0, 3, 2, 1});  // x = 0
    left.face({0, 4, 7, 3});  // y = 0
    left.face({1, 2, 6, 5});  // y = 1
    left.face({0, 1, 5, 4});  // z = 0
    left.face({3, 7, 6, 2});  // z = 1
    for (std::int32_t k = 0; k < 4; ++k) left.face({8, 4 + k, 4 + (k + 1) % 4});
  }
};

// ---------------------------------------------------------------------------------------

TEST(SpherePolyhedronOverlap, BoxesMatchTheBoxClosedForm) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> pos(-1.5, 1.5), ext(0.1, 2.5), rad(0.3, 1.5), unit(0, 1);
  double worst = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const double r = rad(rng);
    Vector3d c(pos(rng), pos(rng), pos(rng));
    const Vector3d lo(pos(rng), pos(rng), pos(rng));
    const Vector3d hi = lo + Vector3d(ext(rng), ext(rng), ext(rng));
    // Every few cases the centre on a face plane, edge or corner of the box.
    if (trial % 5 == 0)
      for (int d = 0; d < 3; ++d)
        if (unit(rng) < 0.5) c[d] = unit(rng) < 0.5 ? lo[d] : hi[d];
    const double reference = sphere_box_overlap(c, r, lo, hi);
    const Polyhedron quads = hexahedron(box_corners(lo, hi));
    const Polyhedron triangles = triangulated(quads, rng);
    const double scale = std::min(ball_volume(r), (hi - lo).prod());
    for (const Polyhedron* p : {&quads, &triangles}) {
      const double v = p->overlap(c, r);
      const double err = std::fabs(v - reference) / scale;
      worst = std::max(worst, err);
      ASSERT_LE(err, 1e-12) << "trial " << trial << " c " << c.transpose() << " r " << r << " lo " << lo.transpose()
                            << " hi " << hi.transpose() << " got " << v << " want " << reference;
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(SpherePolyhedronOverlap, TheQuadratureOracleReproducesTheBoxClosedForm) {
  const Polyhedron box = hexahedron(box_corners(Vector3d(0.1, -0.2, 0.3), Vector3d(1.1, 0.6, 0.9)));
  for (const Vector3d& c : {Vector3d(0.2, 0.1, 0.5), Vector3d(1.0, 0.7, 0.2), Vector3d(0.1, -0.2, 0.3)}) {
    EXPECT_NEAR(integrated_overlap(box, c, 0.7),
                sphere_box_overlap(c, 0.7, Vector3d(0.1, -0.2, 0.3), Vector3d(1.1, 0.6, 0.9)), 1e-13)
        << c.transpose();
  }
}

TEST(SpherePolyhedronOverlap, TetrahedraMatchNumericalIntegration) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> pos(-1, 1), rad(0.3, 1.4);
  for (int trial = 0; trial < 8; ++trial) {
    const Vector3d a(pos(rng), pos(rng), pos(rng)), b(pos(rng), pos(rng), pos(rng)), c(pos(rng), pos(rng), pos(rng)),
        d(pos(rng), pos(rng), pos(rng));
    const double r = rad(rng);
    // Random centres, and the centre on a vertex, an edge and a face.
    for (const Vector3d& centre : {Vector3d(0.5 * Vector3d(pos(rng), pos(rng), pos(rng))), a, Vector3d(0.5 * (a + b)),
                                   Vector3d((a + b + c) / 3)}) {
      const double v = sphere_tetrahedron_overlap(centre, r, a, b, c, d);
      const double reference = integrated_overlap(tetrahedron(a, b, c, d), centre, r);
      ASSERT_NEAR(v, reference, 1e-12 * ball_volume(r)) << "trial " << trial << " centre " << centre.transpose();
      EXPECT_NEAR(v, sphere_tetrahedron_overlap(centre, r, a, c, b, d), 1e-14 * ball_volume(r));  // either orientation
    }
  }
}

TEST(SpherePolyhedronOverlap, SkewHexahedraMatchNumericalIntegration) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1), rad(0.25, 1.0);
  for (int trial = 0; trial < 12; ++trial) {
    const double x0 = 0.4 * u(rng), x1 = 0.6 + 0.6 * u(rng), y0 = 0.4 * u(rng), y1 = 0.6 + 0.6 * u(rng);
    const Matrix3d m = random_map(rng);
    const Polyhedron hex = hexahedron(frustum(x0, x1, y0, y1, 0, 1, m, Vector3d::Zero()));
    ASSERT_GT(hex.volume(), 0);
    const double r = rad(rng);
    const Vector3d centre = m * Vector3d(u(rng), u(rng), u(rng)) + 0.3 * Vector3d(u(rng) - 0.5, u(rng) - 0.5, 0);
    const double v = hex.overlap(centre, r);
    ASSERT_NEAR(v, integrated_overlap(hex, centre, r), 1e-12 * ball_volume(r)) << "trial " << trial;
    EXPECT_GT(v, 0);
  }
}

TEST(SpherePolyhedronOverlap, DegeneratePlacements) {
  const Polyhedron cube = hexahedron(box_corners(Vector3d::Zero(), Vector3d::Ones()));
  const double r = 0.3, ball = ball_volume(r);
  const double tight = 1e-15 * ball;
  // Centre on a face, an edge, a vertex: a half, a quarter, an eighth of the ball.
  EXPECT_NEAR(cube.overlap(Vector3d(0.5, 0.5, 0), r), ball / 2, tight);
  EXPECT_NEAR(cube.overlap(Vector3d(0.5, 1, 0), r), ball / 4, tight);
  EXPECT_NEAR(cube.overlap(Vector3d(1, 1, 1), r), ball / 8, tight);
  // Tangent from inside and from outside: exactly the ball, exactly nothing.
  EXPECT_EQ(cube.overlap(Vector3d(0.5, 0.5, 0.3), r), ball);
  EXPECT_EQ(cube.overlap(Vector3d(0.5, 0.5, 1.3), r), 0.0);
  EXPECT_EQ(cube.overlap(Vector3d(0.5, 0.5, 0.5), r), ball);

  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(0, 0, 1);
  const double tet = 1.0 / 6.0;
  EXPECT_NEAR(sphere_tetrahedron_overlap(Vector3d(0.2, 0.2, 0.2), 2.0, a, b, c, d), tet, 1e-15);  // tet inside
  EXPECT_EQ(sphere_tetrahedron_overlap(Vector3d(0.2, 0.2, 0.2), 0.05, a, b, c, d), ball_volume(0.05));  // ball inside
  // Disjoint: beyond the slanted face but inside the tet's bounding box; far away.
  EXPECT_EQ(sphere_tetrahedron_overlap(Vector3d(0.6, 0.6, 0.6), 0.1, a, b, c, d), 0.0);
  EXPECT_EQ(sphere_tetrahedron_overlap(Vector3d(5, 5, 5), 1.0, a, b, c, d), 0.0);
  // Tangent to the slanted face from outside.
  const double s = 1.0 / 3.0 + 0.1 / std::sqrt(3.0);
  EXPECT_NEAR(sphere_tetrahedron_overlap(Vector3d(s, s, s), 0.1, a, b, c, d), 0.0, 1e-18);
  // Flat and degenerate inputs.
  EXPECT_EQ(sphere_tetrahedron_overlap(Vector3d(0.1, 0.1, 0), 1.0, a, b, c, Vector3d(0.3, 0.3, 0)), 0.0);
  EXPECT_EQ(cube.overlap(Vector3d(0.5, 0.5, 0.5), 0.0), 0.0);
  EXPECT_EQ(cube.overlap(Vector3d(0.5, 0.5, 0.5), -1.0), 0.0);
  // Repeated vertices (zero-length edges, a zero-area face) change nothing.
  Polyhedron repeated;
  repeated.vertices = cube.vertices;
  repeated.vertices.push_back(cube.vertices[1]);  // vertex 8 = vertex 1
  repeated.face({0, 3, 3, 2, 1});
  repeated.face({4, 5, 6, 7});
  repeated.face({0, 8, 5, 4});
  repeated.face({1, 2, 6, 5});
  repeated.face({2, 3, 7, 6});
  repeated.face({3, 0, 4, 7});
  repeated.face({0, 1, 8});
  for (const Vector3d& centre : {Vector3d(0.1, 0.2, 0.9), Vector3d(1, 0, 0.5), Vector3d(0.7, 0.2, -0.1)}) {
    EXPECT_NEAR(repeated.overlap(centre, 0.45), sphere_box_overlap(centre, 0.45, Vector3d::Zero(), Vector3d::Ones()),
                1e-15)
        << centre.transpose();
  }
}

TEST(SpherePolyhedronOverlap, CubeIsTheSumOfItsSixTetrahedra) {
  // Kuhn's triangulation: one tetrahedron per path 0 -> e_i -> e_i + e_j -> (1, 1, 1).
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> pos(-0.5, 1.5), rad(0.1, 1.2);
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int trial = 0; trial < 500; ++trial) {
    const Vector3d c(pos(rng), pos(rng), pos(rng));
    const double r = rad(rng);
    double sum = 0;
    for (const auto& p : perms) {
      Vector3d v1 = Vector3d::Zero();
      v1[p[0]] = 1;
      Vector3d v2 = v1;
      v2[p[1]] = 1;
      sum += sphere_tetrahedron_overlap(c, r, Vector3d::Zero(), v1, v2, Vector3d::Ones());
    }
    ASSERT_NEAR(sum, sphere_box_overlap(c, r, Vector3d::Zero(), Vector3d::Ones()), 1e-13 * ball_volume(r))
        << c.transpose() << " r " << r;
  }
}

TEST(SpherePolyhedronOverlap, PlaneCutsAndSliversAddUp) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1), rad(0.2, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    // A skew frustum cut by a plane into two.
    const double x0 = 0.4 * u(rng), x1 = 0.6 + 0.6 * u(rng), y0 = 0.4 * u(rng), y1 = 0.6 + 0.6 * u(rng);
    const double cut = 0.05 + 0.9 * u(rng);
    const Matrix3d m = random_map(rng);
    const Vector3d shift(u(rng), u(rng), u(rng));
    const Polyhedron whole = hexahedron(frustum(x0, x1, y0, y1, 0, 1, m, shift));
    const Polyhedron below = hexahedron(frustum(x0, x1, y0, y1, 0, cut, m, shift));
    const Polyhedron above = hexahedron(frustum(x0, x1, y0, y1, cut, 1, m, shift));
    const Vector3d c = m * Vector3d(1.4 * u(rng) - 0.2, 1.4 * u(rng) - 0.2, 1.4 * u(rng) - 0.2) + shift;
    const double r = rad(rng);
    ASSERT_NEAR(below.overlap(c, r) + above.overlap(c, r), whole.overlap(c, r), 1e-13 * ball_volume(r)) << trial;

    // A tetrahedron split at a point near an edge (a needle) and near a face edge (a flat sliver).
    const Vector3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), cc(u(rng), u(rng), u(rng)),
        d(u(rng), u(rng), u(rng));
    const double whole_tet = sphere_tetrahedron_overlap(c, r, a, b, cc, d);
    const double eps = std::pow(10.0, -3 - 10 * u(rng));
    const Vector3d needle = a + eps * (b - a);
    EXPECT_NEAR(sphere_tetrahedron_overlap(c, r, a, needle, cc, d) + sphere_tetrahedron_overlap(c, r, needle, b, cc, d),
                whole_tet, 1e-13 * ball_volume(r));
    const Vector3d flat = (1 - eps) * (0.5 * (a + b)) + eps * cc;  // just inside face abc, near edge ab
    const double parts = sphere_tetrahedron_overlap(c, r, a, b, flat, d) +
                         sphere_tetrahedron_overlap(c, r, b, cc, flat, d) +
                         sphere_tetrahedron_overlap(c, r, cc, a, flat, d);
    EXPECT_NEAR(parts, whole_tet, 1e-13 * ball_volume(r));
    const double sliver = sphere_tetrahedron_overlap(c, r, a, b, flat, d);
    EXPECT_GE(sliver, 0);
    EXPECT_LE(sliver, std::fabs((b - a).cross(flat - a).dot(d - a)) / 6 + 1e-15 * ball_volume(r));
  }
}

TEST(SpherePolyhedronOverlap, NonConvexAndWarpedFanCellsAddUp) {
  // An L-shaped prism (non-convex, with non-convex L faces) = two boxes.
  Polyhedron l;
  l.vertices = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0},
                {0, 0, 1}, {2, 0, 1}, {2, 1, 1}, {1, 1, 1}, {1, 2, 1}, {0, 2, 1}};
  l.face({0, 5, 4, 3, 2, 1});
  l.face({6, 7, 8, 9, 10, 11});
  for (std::int32_t k = 0; k < 6; ++k) l.face({k, (k + 1) % 6, (k + 1) % 6 + 6, k + 6});
  EXPECT_NEAR(l.volume(), 3.0, 1e-15);

  // WarpedSplit's two cells.
  const WarpedSplit split;
  const auto& warped = split.quad;
  const Vector3d& apex = split.apex;
  const Polyhedron& left = split.left;
  Polyhedron right;
  right.vertices = {{2, 0, 0}, {2, 1, 0}, {2, 1, 1}, {2, 0, 1}, warped[0], warped[1], warped[2], warped[3], apex};
  right.face({0, 1, 2, 3});    // x = 2
  right.face({4, 0, 3, 7});    // y = 0
  right.face({5, 6, 2, 1});    // y = 1
  right.face({4, 5, 1, 0});    // z = 0
  right.face({7, 3, 2, 6});    // z = 1
  for (std::int32_t k = 0; k < 4; ++k) right.face({8, 4 + (k + 1) % 4, 4 + k});
  EXPECT_NEAR(left.volume() + right.volume(), 2.0, 1e-15);

  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> pos(-0.5, 2.5), rad(0.1, 1.5);
  for (int trial = 0; trial < 1000; ++trial) {
    const Vector3d c(pos(rng), pos(rng), pos(rng) * 0.6);
    const double r = rad(rng);
    const double boxes = sphere_box_overlap(c, r, Vector3d(0, 0, 0), Vector3d(2, 1, 1)) +
                         sphere_box_overlap(c, r, Vector3d(0, 1, 0), Vector3d(1, 2, 1));
    ASSERT_NEAR(l.overlap(c, r), boxes, 1e-13 * ball_volume(r)) << c.transpose() << " r " << r;
    const double lv = left.overlap(c, r), rv = right.overlap(c, r);
    ASSERT_NEAR(lv + rv, sphere_box_overlap(c, r, Vector3d::Zero(), Vector3d(2, 1, 1)), 1e-13 * ball_volume(r))
        << c.transpose() << " r " << r;
    ASSERT_GE(lv, 0);
    ASSERT_GE(rv, 0);
  }
}

TEST(SpherePolyhedronOverlap, RandomInputsStayFiniteAndBounded) {
  // Vertices on a coarse lattice, so centres often sit on vertices, edges and faces.
  std::mt19937_64 rng(17);
  std::uniform_int_distribution<int> lattice(-2, 2);
  std::uniform_real_distribution<double> rad(0.1, 3.0);
  for (int trial = 0; trial < 5000; ++trial) {
    const auto point = [&]() -> Vector3d { return 0.5 * Vector3d(lattice(rng), lattice(rng), lattice(rng)); };
    const Vector3d a = point(), b = point(), c = point(), d = point(), centre = point();
    const double r = rad(rng);
    const double v = sphere_tetrahedron_overlap(centre, r, a, b, c, d);
    const double tet = std::fabs((b - a).cross(c - a).dot(d - a)) / 6;
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0);
    ASSERT_LE(v, std::min(tet, ball_volume(r)) * (1 + 1e-12));
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------
// The located overlap: the centre's side known, only the faces that reach into the ball

namespace located {

using vfe::kernels::sphere_polyhedron_overlap_located;

/// True when c lies strictly inside every face plane of the convex polyhedron p (planar faces).
bool inside_convex(const Polyhedron& p, const Vector3d& c) {
  for (std::size_t f = 0; f + 1 < p.offsets.size(); ++f) {
    const Vector3d& a = p.vertices[p.indices[p.offsets[f]]];
    const Vector3d n = (p.vertices[p.indices[p.offsets[f] + 1]] - a).cross(p.vertices[p.indices[p.offsets[f] + 2]] - a);
    if (n.dot(c - a) >= 0) return false;
  }
  return true;
}

/// p's faces whose plane comes within `reach` of c (the rest cannot reach into the ball), with
/// only the vertices they use.
Polyhedron faces_near(const Polyhedron& p, const Vector3d& c, double reach) {
  Polyhedron near;
  for (std::size_t f = 0; f + 1 < p.offsets.size(); ++f) {
    const std::int32_t begin = p.offsets[f], end = p.offsets[f + 1];
    Vector3d area = Vector3d::Zero();
    for (std::int32_t k = begin; k < end; ++k)
      area += p.vertices[p.indices[k]].cross(p.vertices[p.indices[k + 1 == end ? begin : k + 1]]);
    const Vector3d n = area.normalized();
    if (std::fabs(n.dot(c - p.vertices[p.indices[begin]])) > reach) continue;
    for (std::int32_t k = begin; k < end; ++k) {
      near.vertices.push_back(p.vertices[p.indices[k]]);
      near.indices.push_back(static_cast<std::int32_t>(near.vertices.size() - 1));
    }
    near.offsets.push_back(static_cast<std::int32_t>(near.indices.size()));
  }
  return near;
}

std::optional<double> overlap_located(const Polyhedron& p, const Vector3d& c, double r, bool inside) {
  return sphere_polyhedron_overlap_located(c, r, inside, p.vertices, p.offsets, p.indices);
}

/// The located overlap from `part` of `whole`'s faces, or (counted in `declined`) the
/// general one of `whole` where the located one declines, as the engine does.
double located_or_general(const Polyhedron& whole, const Polyhedron& part, const Vector3d& c, double r, bool inside,
                          int& declined) {
  if (const std::optional<double> v = overlap_located(part, c, r, inside)) return *v;
  ++declined;
  return whole.overlap(c, r);
}

}  // namespace located

TEST(SpherePolyhedronOverlapLocated, SkewHexahedraMatchNumericalIntegrationFromTheNearFacesOnly) {
  using namespace located;
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(0, 1), rad(0.2, 0.9);
  int inside_count = 0, partial = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const double x0 = 0.4 * u(rng), x1 = 0.6 + 0.6 * u(rng), y0 = 0.4 * u(rng), y1 = 0.6 + 0.6 * u(rng);
    const Matrix3d m = random_map(rng);
    const Polyhedron hex = hexahedron(frustum(x0, x1, y0, y1, 0, 1, m, Vector3d::Zero()));
    const double r = rad(rng);
    const Vector3d c = m * Vector3d(1.2 * u(rng) - 0.1, 1.2 * u(rng) - 0.1, 1.2 * u(rng) - 0.1);
    const bool inside = inside_convex(hex, c);
    const Polyhedron near = faces_near(hex, c, r);
    inside_count += inside;
    partial += near.offsets.size() < hex.offsets.size();
    const double reference = integrated_overlap(hex, c, r);
    int declined = 0;
    ASSERT_NEAR(located_or_general(hex, hex, c, r, inside, declined), reference, 1e-12 * ball_volume(r)) << trial;
    ASSERT_NEAR(located_or_general(hex, near, c, r, inside, declined), reference, 1e-12 * ball_volume(r)) << trial;
    ASSERT_EQ(declined, 0) << "trial " << trial;  // random centres are far from the edges
  }
  // Both sides of the surface, and faces left out, were exercised.
  EXPECT_GT(inside_count, 4);
  EXPECT_LT(inside_count, 20);
  EXPECT_GT(partial, 4);
}

TEST(SpherePolyhedronOverlapLocated, EqualsTheGeneralOverlapOnBoxesAndNonConvexCells) {
  using namespace located;
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> pos(-0.5, 2.5), rad(0.05, 1.5), unit(0, 1);
  Polyhedron l;  // the L-shaped prism of NonConvexAndWarpedFanCellsAddUp: [0,2]x[0,1] and [0,1]x[1,2], z in [0,1]
  l.vertices = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0},
                {0, 0, 1}, {2, 0, 1}, {2, 1, 1}, {1, 1, 1}, {1, 2, 1}, {0, 2, 1}};
  l.face({0, 5, 4, 3, 2, 1});
  l.face({6, 7, 8, 9, 10, 11});
  for (std::int32_t k = 0; k < 6; ++k) l.face({k, (k + 1) % 6, (k + 1) % 6 + 6, k + 6});
  const Vector3d lo(0.1, 0.2, 0.3), hi(0.9, 1.7, 1.1);
  const Polyhedron box = hexahedron(box_corners(lo, hi));
  int declined = 0;
  const int trials = 4000;
  for (int trial = 0; trial < trials; ++trial) {
    const Vector3d c(pos(rng), pos(rng), pos(rng) * 0.6);
    const double r = rad(rng);
    const double ball = ball_volume(r);
    const auto in_box = [](const Vector3d& p, const Vector3d& a, const Vector3d& b) {
      return (p.array() > a.array()).all() && (p.array() < b.array()).all();
    };
    const bool in_l = in_box(c, Vector3d(0, 0, 0), Vector3d(2, 1, 1)) || in_box(c, Vector3d(0, 0, 0), Vector3d(1, 2, 1));
    const double l_exact = sphere_box_overlap(c, r, Vector3d(0, 0, 0), Vector3d(2, 1, 1)) +
                           sphere_box_overlap(c, r, Vector3d(0, 1, 0), Vector3d(1, 2, 1));
    ASSERT_NEAR(located_or_general(l, l, c, r, in_l, declined), l_exact, 1e-13 * ball) << c.transpose() << " r " << r;
    ASSERT_NEAR(located_or_general(l, faces_near(l, c, r), c, r, in_l, declined), l_exact, 1e-13 * ball)
        << c.transpose();
    const double box_exact = sphere_box_overlap(c, r, lo, hi);
    const bool in = in_box(c, lo, hi);
    ASSERT_NEAR(located_or_general(box, faces_near(box, c, r), c, r, in, declined), box_exact, 1e-13 * ball)
        << c.transpose();
    ASSERT_NEAR(located_or_general(box, box, c, r, in, declined), box.overlap(c, r), 1e-13 * ball) << c.transpose();
  }
  // Declining is for centres near an edge the ball reaches: a few in a hundred here.
  EXPECT_LT(declined, 4 * trials / 20);
}

TEST(SpherePolyhedronOverlapLocated, CentresNearAnEdgeOrTheApexOfAWarpedFanTakeTheGeneralFormula) {
  using namespace located;
  // WarpedSplit's left cell: a warped quad as a fan about its apex.
  const WarpedSplit split;
  const Vector3d& apex = split.apex;
  const Polyhedron& left = split.left;
  const double r = 0.3, ball = ball_volume(r);
  // Beside the apex the fan triangles' solid angles change by O(1) within the distance
  // to it; the located sum would lose digits (about 1e-17 of the ball over the distance).
  for (const double delta : {1e-3, 1e-6, 1e-9, -1e-9, 1e-12}) {
    const Vector3d c = apex + Vector3d(delta, 0, 0);
    EXPECT_FALSE(overlap_located(left, c, r, delta < 0).has_value()) << delta;
  }
  // At a tenth of the cell from the apex and its spokes the located sum is accurate.
  const Vector3d c = apex + Vector3d(-0.15, 0.1, 0.05);
  const std::optional<double> v = overlap_located(left, c, r, true);
  ASSERT_TRUE(v.has_value());
  EXPECT_NEAR(*v, left.overlap(c, r), 1e-15 * ball);
  // Near a box edge both faces' lines are near: declined too.
  const Polyhedron cube = hexahedron(box_corners(Vector3d::Zero(), Vector3d::Ones()));
  EXPECT_FALSE(overlap_located(cube, Vector3d(0.5, 1e-5, 1e-5), r, true).has_value());
  EXPECT_NEAR(overlap_located(cube, Vector3d(0.5, 0.05, 0.05), r, true).value(),
              sphere_box_overlap(Vector3d(0.5, 0.05, 0.05), r, Vector3d::Zero(), Vector3d::Ones()), 1e-15 * ball);
}

TEST(SpherePolyhedronOverlapLocated, ACentreOnAReachingFacePlaneAsksForTheWholeSurface) {
  using namespace located;
  const Polyhedron cube = hexahedron(box_corners(Vector3d::Zero(), Vector3d::Ones()));
  const double r = 0.3, ball = ball_volume(r);
  // On the face z = 0, and within rounding of it: the side is unsure, no value.
  EXPECT_FALSE(overlap_located(cube, Vector3d(0.5, 0.5, 0), r, true).has_value());
  EXPECT_FALSE(overlap_located(cube, Vector3d(0.5, 0.5, 1e-15), r, true).has_value());
  EXPECT_FALSE(overlap_located(cube, Vector3d(0.5, 0.5, -1e-15), r, false).has_value());
  // 1e-9 away the side is clear, and the volume is the closed form's.
  for (const double z : {1e-9, -1e-9, 1e-6}) {
    const Vector3d c(0.5, 0.5, z);
    EXPECT_NEAR(overlap_located(cube, c, r, z > 0).value(), sphere_box_overlap(c, r, Vector3d::Zero(), Vector3d::Ones()),
                1e-15 * ball)
        << z;
  }
  // A plane through the centre whose face stays out of the ball is no reason to refuse.
  const Vector3d beside(0.5, 0.5 + 1 + 0.5, 0);  // in the plane z = 0, 1.5 beyond y = 1
  EXPECT_EQ(overlap_located(cube, beside, 0.3, false), 0.0);
  // No face given: the ball is wholly on the side the caller located.
  const Polyhedron none;
  EXPECT_EQ(overlap_located(none, Vector3d(0.5, 0.5, 0.5), r, true), ball);
  EXPECT_EQ(overlap_located(none, Vector3d(0.5, 0.5, 0.5), r, false), 0.0);
}

TEST(SpherePolyhedronOverlapLocated, FaceTermsSharedByTwoCellsMatchNumericalIntegration) {
  using namespace located;
  using vfe::kernels::sphere_face_located_term;
  using vfe::kernels::sphere_located_overlap;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0, 1), rad(0.2, 0.9);
  // Face f of p as a polygon, in p's (outward) orientation or reversed.
  const auto polygon = [](const Polyhedron& p, std::size_t f, bool reversed) {
    std::vector<Vector3d> points;
    for (std::int32_t k = p.offsets[f]; k < p.offsets[f + 1]; ++k) points.push_back(p.vertices[p.indices[k]]);
    if (reversed) std::reverse(points.begin(), points.end());
    return points;
  };
  int declined = 0, shared_reached = 0;
  const int trials = 40;
  for (int trial = 0; trial < trials; ++trial) {
    // Two skew hexahedra stacked along z: the lower one's top face (face 1) is the upper
    // one's bottom face (face 0), reversed.
    const double x0 = 0.4 * u(rng), x1 = 0.6 + 0.6 * u(rng), y0 = 0.4 * u(rng), y1 = 0.6 + 0.6 * u(rng);
    const Matrix3d m = random_map(rng);
    const Polyhedron lower = hexahedron(frustum(x0, x1, y0, y1, 0, 0.5, m, Vector3d::Zero()));
    const Polyhedron upper = hexahedron(frustum(x0, x1, y0, y1, 0.5, 1, m, Vector3d::Zero()));
    const double r = rad(rng), ball = ball_volume(r);
    const Vector3d c = m * Vector3d(1.2 * u(rng) - 0.1, 1.2 * u(rng) - 0.1, 1.2 * u(rng) - 0.1);
    const std::optional<double> shared = sphere_face_located_term(c, r, polygon(lower, 1, false));
    const std::optional<double> shared_reversed = sphere_face_located_term(c, r, polygon(upper, 0, false));
    if (!shared || !shared_reversed) {
      ++declined;
      continue;
    }
    shared_reached += *shared != 0;
    // The other cell sees the face reversed: the negated term, to round-off.
    ASSERT_NEAR(*shared_reversed, -*shared, 1e-14 * ball) << trial;
    const auto cell_overlap = [&](const Polyhedron& p, std::size_t shared_face, double shared_term) {
      double sum = 0;
      for (std::size_t f = 0; f + 1 < p.offsets.size(); ++f) {
        if (f == shared_face) {
          sum += shared_term;
          continue;
        }
        const std::optional<double> term = sphere_face_located_term(c, r, polygon(p, f, false));
        if (!term) return std::optional<double>();
        sum += *term;
      }
      return std::optional<double>(sphere_located_overlap(r, inside_convex(p, c), sum));
    };
    const std::optional<double> v_lower = cell_overlap(lower, 1, *shared), v_upper = cell_overlap(upper, 0, -*shared);
    if (!v_lower || !v_upper) {
      ++declined;
      continue;
    }
    ASSERT_NEAR(*v_lower, integrated_overlap(lower, c, r), 1e-12 * ball) << trial;
    ASSERT_NEAR(*v_upper, integrated_overlap(upper, c, r), 1e-12 * ball) << trial;
    // The same as the located overlap of each cell's whole surface.
    ASSERT_NEAR(*v_lower, overlap_located(lower, c, r, inside_convex(lower, c)).value(), 1e-14 * ball) << trial;
  }
  EXPECT_LT(declined, trials / 10);  // random centres are far from the edges
  EXPECT_GT(shared_reached, trials / 4);  // the shared face mattered
  // A face out of the ball's reach adds nothing; a centre on the face's plane has no term.
  const Polyhedron cube = hexahedron(box_corners(Vector3d::Zero(), Vector3d::Ones()));
  EXPECT_EQ(sphere_face_located_term(Vector3d(0.5, 0.5, 3), 0.3, polygon(cube, 0, false)), 0.0);
  EXPECT_FALSE(sphere_face_located_term(Vector3d(0.5, 0.5, 0), 0.3, polygon(cube, 0, false)).has_value());
  EXPECT_EQ(sphere_located_overlap(0.3, true, 0.0), ball_volume(0.3));
}

TEST(SpherePolyhedronOverlapLocated, AWarpedFansTermIsTheSumOfItsTrianglesAndClosesTheBoxItSplits) {
  using vfe::kernels::sphere_face_located_term;
  using vfe::kernels::sphere_fan_located_term;
  using vfe::kernels::sphere_located_overlap;
  // The sum of the triangles' own terms, or none where one declines.
  const auto triangles = [](const Vector3d& c, double r, const Vector3d& apex, const std::vector<Vector3d>& rim) {
    double sum = 0;
    for (std::size_t i = 0; i < rim.size(); ++i) {
      const std::array<Vector3d, 3> t{apex, rim[i], rim[(i + 1) % rim.size()]};
      const std::optional<double> term = sphere_face_located_term(c, r, t);
      if (!term) return std::optional<double>();
      sum += *term;
    }
    return std::optional<double>(sum);
  };
  std::mt19937_64 rng(47);
  std::uniform_real_distribution<double> u(-1, 1), rad(0.1, 1.2);
  int reached = 0, declined = 0;
  // Warped rims of 3 to 40 points (over 32 the triangles are taken one by one) about the
  // unit circle in z = 0, their points lifted at random, the apex at the points' mean.
  for (int trial = 0; trial < 3000; ++trial) {
    const int n = 3 + trial % 38;
    std::vector<Vector3d> rim;
    for (int i = 0; i < n; ++i) {
      const double angle = 2 * kPi * (i + 0.3 * u(rng)) / n;
      rim.emplace_back(std::cos(angle), std::sin(angle), 0.2 * u(rng));
    }
    Vector3d apex = Vector3d::Zero();
    for (const Vector3d& p : rim) apex += p / n;
    const Vector3d c(1.5 * u(rng), 1.5 * u(rng), 0.8 * u(rng));
    const double r = rad(rng), ball = ball_volume(r);
    const std::optional<double> fan = sphere_fan_located_term(c, r, apex, rim);
    const std::optional<double> sum = triangles(c, r, apex, rim);
    // Both decline together (near a spoke's or a side's line).
    ASSERT_EQ(fan.has_value(), sum.has_value()) << trial;
    if (!fan) {
      ++declined;
      continue;
    }
    reached += *sum != 0;
    ASSERT_NEAR(*fan, *sum, 1e-14 * ball) << "trial " << trial << " n " << n;
    // Reversed, the term is negated.
    std::vector<Vector3d> reversed(rim.rbegin(), rim.rend());
    if (const std::optional<double> back = sphere_fan_located_term(c, r, apex, reversed)) {
      ASSERT_NEAR(*back, -*fan, 1e-14 * ball) << trial;
    }
  }
  EXPECT_GT(reached, 1500);
  EXPECT_LT(declined, 30);
  // A fan whose box misses the ball adds exactly nothing; a centre on a reaching
  // triangle's plane (here the first triangle's, z = 0) has no term.
  const std::vector<Vector3d> square{{0, 0, 0}, {1, 0, 0}, {1, 1, 0.1}, {0, 1, -0.1}};
  const Vector3d apex(0.5, 0.5, 0);
  EXPECT_EQ(sphere_fan_located_term(Vector3d(0.5, 0.5, 2), 0.5, apex, square), 0.0);
  EXPECT_FALSE(sphere_fan_located_term(Vector3d(0.5, 0.2, 0), 0.3, apex, square).has_value());
  EXPECT_TRUE(sphere_fan_located_term(Vector3d(0.5, 0.2, 0.05), 0.3, apex, square).has_value());

  // An independent closed form: WarpedSplit's two cells' located overlaps, each from its
  // faces' terms (the fan's term shared, negated for the right cell), add up to the box's.
  const WarpedSplit split;
  const std::vector<Vector3d> warped(split.quad.begin(), split.quad.end());
  const Vector3d& middle = split.apex;
  const auto quad = [](Vector3d a, Vector3d b, Vector3d c, Vector3d d) { return std::vector<Vector3d>{a, b, c, d}; };
  int closed = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Vector3d c(1 + 0.9 * u(rng), 0.5 + 0.45 * u(rng), 0.5 + 0.45 * u(rng));
    const double r = 0.5 * rad(rng), ball = ball_volume(r);
    const std::optional<double> shared = sphere_fan_located_term(c, r, middle, warped);
    if (!shared) continue;
    // Outward faces of the left cell (x = 0 side) besides the fan, then of the right cell.
    const std::vector<std::vector<Vector3d>> left_faces{
        quad({0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}), quad({0, 0, 0}, warped[0], warped[3], {0, 0, 1}),
        quad({0, 1, 0}, {0, 1, 1}, warped[2], warped[1]), quad({0, 0, 0}, {0, 1, 0}, warped[1], warped[0]),
        quad({0, 0, 1}, warped[3], warped[2], {0, 1, 1})};
    const std::vector<std::vector<Vector3d>> right_faces{
        quad({2, 0, 0}, {2, 1, 0}, {2, 1, 1}, {2, 0, 1}), quad(warped[0], {2, 0, 0}, {2, 0, 1}, warped[3]),
        quad(warped[1], warped[2], {2, 1, 1}, {2, 1, 0}), quad(warped[0], warped[1], {2, 1, 0}, {2, 0, 0}),
        quad(warped[3], {2, 0, 1}, {2, 1, 1}, warped[2])};
    const auto cell = [&](const std::vector<std::vector<Vector3d>>& faces, double fan_term, bool inside) {
      double sum = fan_term;
      for (const auto& face : faces) {
        const std::optional<double> term = sphere_face_located_term(c, r, face);
        if (!term) return std::optional<double>();
        sum += *term;
      }
      return std::optional<double>(sphere_located_overlap(r, inside, sum));
    };
    // Which cell holds the centre: whether a tiny ball about it lies in the left one.
    const Polyhedron& left = split.left;
    const double general_left = left.overlap(c, r);
    const bool in_left = left.overlap(c, 1e-9) > 0.5 * ball_volume(1e-9);
    const std::optional<double> lv = cell(left_faces, *shared, in_left), rv = cell(right_faces, -*shared, !in_left);
    if (!lv || !rv) continue;
    ASSERT_NEAR(*lv + *rv, sphere_box_overlap(c, r, Vector3d::Zero(), Vector3d(2, 1, 1)), 1e-13 * ball) << trial;
    ASSERT_NEAR(*lv, general_left, 1e-13 * ball) << trial;
    closed += *shared != 0;
  }
  EXPECT_GT(closed, 150);  // the fan cut about a third of the balls
}

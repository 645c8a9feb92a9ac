#include <vfe/kernels/gaussian_polyhedron.hpp>

#include <vfe/kernels/gaussian.hpp>

#include <cmath>
#include <numbers>

namespace vfe::kernels {

namespace {

constexpr int kMaxDepth = 6;

/// The normalised, cut kernel in units of sigma about the centre: exp(-|u|^2/2) over
/// (2 pi)^(3/2) times the cut box's mass, erf(3 / sqrt 2)^3.
struct UnitKernel {
  double scale;
  double operator()(const Eigen::Vector3d& u) const { return scale * std::exp(-0.5 * u.squaredNorm()); }
};

UnitKernel unit_kernel() {
  const double axis = std::erf(kGaussianCut / std::numbers::sqrt2);
  return {1.0 / (std::pow(2 * std::numbers::pi, 1.5) * axis * axis * axis)};
}

/// Integral over the tetrahedron (a, b, c, d) whose degree-5 value is `coarse`: split into
/// 8 (corners and the octahedron cut along m02-m13) until the levels agree to `tol`.
double adapt(const UnitKernel& g, const TetrahedronRule& rule, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
             const Eigen::Vector3d& c, const Eigen::Vector3d& d, double coarse, double tol, int depth) {
  const Eigen::Vector3d m01 = 0.5 * (a + b), m02 = 0.5 * (a + c), m03 = 0.5 * (a + d), m12 = 0.5 * (b + c),
                        m13 = 0.5 * (b + d), m23 = 0.5 * (c + d);
  const std::array<std::array<const Eigen::Vector3d*, 4>, 8> kids{{{&a, &m01, &m02, &m03},
                                                                   {&m01, &b, &m12, &m13},
                                                                   {&m02, &m12, &c, &m23},
                                                                   {&m03, &m13, &m23, &d},
                                                                   {&m02, &m13, &m01, &m12},
                                                                   {&m02, &m13, &m12, &m23},
                                                                   {&m02, &m13, &m23, &m03},
                                                                   {&m02, &m13, &m03, &m01}}};
  std::array<double, 8> value;
  double fine = 0;
  for (std::size_t k = 0; k < 8; ++k) {
    value[k] = integrate_tetrahedron(g, *kids[k][0], *kids[k][1], *kids[k][2], *kids[k][3], rule);
    fine += value[k];
  }
  // The degree-5 rule's error falls by 2^6 per split, so fine's error is about
  // |fine - coarse| / 63: accepting at 15 tol keeps a margin of 4.
  if (depth >= kMaxDepth || std::fabs(fine - coarse) <= 15 * tol) return fine;
  double sum = 0;
  for (std::size_t k = 0; k < 8; ++k)
    sum += adapt(g, rule, *kids[k][0], *kids[k][1], *kids[k][2], *kids[k][3], value[k], tol / 8, depth + 1);
  return sum;
}

/// Signed mass of one tetrahedron given in units of sigma about the centre.
double unit_tetrahedron_mass(const UnitKernel& g, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c, const Eigen::Vector3d& d, double tolerance) {
  const double six = (b - a).dot((c - a).cross(d - a));
  if (six == 0) return 0;
  const Eigen::Vector3d lo = Eigen::Vector3d::Constant(-kGaussianCut), hi = Eigen::Vector3d::Constant(kGaussianCut);
  const Eigen::Vector3d tlo = a.cwiseMin(b).cwiseMin(c.cwiseMin(d)), thi = a.cwiseMax(b).cwiseMax(c.cwiseMax(d));
  if ((tlo.cwiseMax(lo).array() >= thi.cwiseMin(hi).array()).any()) return 0;
  ConvexPolytope p = ConvexPolytope::tetrahedron(a, b, c, d);
  p.clip_box(lo, hi);
  const TetrahedronRule& rule = tetrahedron_rule(5);
  const double box_volume = std::pow(2 * kGaussianCut, 3);
  double mass = 0;
  p.for_each_tetrahedron([&](const Eigen::Vector3d& o, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                             const Eigen::Vector3d& p3) {
    const double volume = signed_tetrahedron_volume(o, p1, p2, p3);
    const double coarse = integrate_tetrahedron(g, o, p1, p2, p3, rule);
    // Slivers of round-off size (clips through vertices) hold no mass worth refining,
    // and their share of the tolerance would be 0.
    if (std::fabs(volume) <= 1e-12 * box_volume) {
      mass += coarse;
      return;
    }
    mass += adapt(g, rule, o, p1, p2, p3, coarse, tolerance * std::fabs(volume) / box_volume, 1);
  });
  return six > 0 ? mass : -mass;
}

}  // namespace

double gaussian_polyhedron_integral(const Eigen::Vector3d& centre, double sigma, TetrahedraView tets,
                                    double tolerance) {
  const UnitKernel g = unit_kernel();
  const double inv = 1.0 / sigma;
  double mass = 0;
  for (std::size_t t = 0; t + 3 < tets.size(); t += 4)
    mass += unit_tetrahedron_mass(g, (tets[t] - centre) * inv, (tets[t + 1] - centre) * inv,
                                  (tets[t + 2] - centre) * inv, (tets[t + 3] - centre) * inv, tolerance);
  return mass;
}

double gaussian_polyhedron_integral(const Eigen::Vector3d& centre, double sigma,
                                    std::span<const Eigen::Vector3d> vertices,
                                    std::span<const std::int32_t> face_offsets,
                                    std::span<const std::int32_t> face_vertices, double tolerance) {
  const UnitKernel g = unit_kernel();
  const double inv = 1.0 / sigma;
  double mass = 0;
  for_each_face_tetrahedron(vertices, face_offsets, face_vertices,
                            [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                const Eigen::Vector3d& d) {
                              mass += unit_tetrahedron_mass(g, (a - centre) * inv, (b - centre) * inv,
                                                            (c - centre) * inv, (d - centre) * inv, tolerance);
                            });
  return mass;
}

}  // namespace vfe::kernels

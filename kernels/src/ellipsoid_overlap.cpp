#include <vfe/kernels/ellipsoid_overlap.hpp>

#include <vfe/kernels/sphere_polyhedron_overlap.hpp>

#include <array>
#include <numbers>

namespace vfe::kernels {

double Ellipsoid::volume() const { return 4.0 / 3.0 * std::numbers::pi * semi_axes.prod(); }

Eigen::Matrix3d Ellipsoid::to_unit() const {
  return semi_axes.cwiseInverse().asDiagonal() * rotation.transpose();
}

double ellipsoid_polyhedron_overlap(const Ellipsoid& e, std::span<const Eigen::Vector3d> vertices,
                                    std::span<const std::int32_t> face_offsets,
                                    std::span<const std::int32_t> face_vertices, std::span<Eigen::Vector3d> scratch) {
  if (scratch.size() < vertices.size() || vertices.empty()) return 0;
  const Eigen::Matrix3d m = e.to_unit();
  for (std::size_t i = 0; i < vertices.size(); ++i) scratch[i] = m * (vertices[i] - e.centre);
  // A reflection reverses the faces' orientation: mirror the mapped cell through the
  // ball's centre (the ball is symmetric), which reverses it back.
  if (m.determinant() < 0)
    for (std::size_t i = 0; i < vertices.size(); ++i) scratch[i] = -scratch[i];
  const double unit = sphere_polyhedron_overlap(Eigen::Vector3d::Zero(), 1.0, scratch.first(vertices.size()),
                                                face_offsets, face_vertices);
  const double full = 4.0 / 3.0 * std::numbers::pi;
  // Keep the exact end values exact: the whole ellipsoid is exactly its volume.
  return unit == full ? e.volume() : unit * e.semi_axes.prod();
}

double ellipsoid_box_overlap(const Ellipsoid& e, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  if (!((hi - lo).minCoeff() > 0)) return 0;
  // Corners i + 2 j + 4 k; faces counter-clockwise seen from outside.
  std::array<Eigen::Vector3d, 8> corners;
  for (int k = 0; k < 8; ++k) corners[static_cast<std::size_t>(k)] = {k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]};
  static constexpr std::array<std::int32_t, 7> kOffsets{0, 4, 8, 12, 16, 20, 24};
  static constexpr std::array<std::int32_t, 24> kFaces{0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4,
                                                       2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
  std::array<Eigen::Vector3d, 8> scratch;
  return ellipsoid_polyhedron_overlap(e, corners, kOffsets, kFaces, scratch);
}

double ellipsoid_tetrahedron_overlap(const Ellipsoid& e, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                     const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const Eigen::Matrix3d m = e.to_unit();
  const Eigen::Vector3d ua = m * (a - e.centre), ub = m * (b - e.centre), uc = m * (c - e.centre),
                        ud = m * (d - e.centre);
  // sphere_tetrahedron_overlap is unsigned; the sign is the original orientation's.
  const double unit = sphere_tetrahedron_overlap(Eigen::Vector3d::Zero(), 1.0, ua, ub, uc, ud);
  const double six = (b - a).dot((c - a).cross(d - a));
  const double full = 4.0 / 3.0 * std::numbers::pi;
  const double v = unit == full ? e.volume() : unit * e.semi_axes.prod();
  return six < 0 ? -v : v;
}

double ellipsoid_polyhedron_overlap(const Ellipsoid& e, TetrahedraView tets) {
  double v = 0;
  for (std::size_t t = 0; t + 3 < tets.size(); t += 4) v += ellipsoid_tetrahedron_overlap(e, tets[t], tets[t + 1], tets[t + 2], tets[t + 3]);
  return v;
}

}  // namespace vfe::kernels

#include <vfe/kernels/mesh_overlap.hpp>

#include <array>

namespace vfe::kernels {

namespace {

/// Calls f(o, a, b, c) for the placed mesh's tetrahedra from o (the placed centre of its
/// vertices' box: near the triangles, so little cancellation) to each triangle, oriented
/// so their signed volumes sum to the placed mesh's volume (> 0 even for a reflection).
template <class F>
void for_each_particle_tetrahedron(const PlacedMesh& m, F&& f) {
  const TriangleMesh& mesh = *m.mesh;
  if (mesh.vertices.empty()) return;
  Eigen::AlignedBox3d box;
  for (const auto& v : mesh.vertices) box.extend(v);
  const Eigen::Vector3d o = m.translation + m.linear * box.center();
  const bool mirrored = m.linear.determinant() < 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d a = m.translation + m.linear * mesh.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3d b = m.translation + m.linear * mesh.vertices[static_cast<std::size_t>(t[1])];
    const Eigen::Vector3d c = m.translation + m.linear * mesh.vertices[static_cast<std::size_t>(t[2])];
    if (mirrored)
      f(o, a, c, b);
    else
      f(o, a, b, c);
  }
}

/// Outward planes (n, d), n . x <= d inside, of the tetrahedron (a, b, c, d), either
/// orientation.
std::array<Eigen::Vector4d, 4> tetrahedron_planes(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                                  const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const std::array<const Eigen::Vector3d*, 4> p{&a, &b, &c, &d};
  std::array<Eigen::Vector4d, 4> planes;
  for (std::size_t k = 0; k < 4; ++k) {
    // Face opposite corner k; its normal points away from corner k.
    const Eigen::Vector3d& u = *p[(k + 1) % 4];
    const Eigen::Vector3d& v = *p[(k + 2) % 4];
    const Eigen::Vector3d& w = *p[(k + 3) % 4];
    Eigen::Vector3d n = (v - u).cross(w - u);
    if (n.dot(*p[k] - u) > 0) n = -n;
    planes[k] << n, n.dot(u);
  }
  return planes;
}

bool boxes_meet(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
                const Eigen::Vector3d& hi2) {
  return (lo1.cwiseMax(lo2).array() < hi1.cwiseMin(hi2).array()).all();
}

}  // namespace

double mesh_halfspaces_overlap(const PlacedMesh& m, std::span<const Eigen::Vector4d> planes) {
  double v = 0;
  for_each_particle_tetrahedron(m, [&](const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c) { v += tetrahedron_halfspaces_overlap(o, a, b, c, planes); });
  return v;
}

double mesh_box_overlap(const PlacedMesh& m, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  double v = 0;
  for_each_particle_tetrahedron(m, [&](const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c) { v += tetrahedron_box_overlap(o, a, b, c, lo, hi); });
  return v;
}

double mesh_polyhedron_overlap(const PlacedMesh& m, TetrahedraView cell_tets) {
  double v = 0;
  for (std::size_t t = 0; t + 3 < cell_tets.size(); t += 4) {
    const Eigen::Vector3d &p = cell_tets[t], &q = cell_tets[t + 1], &r = cell_tets[t + 2], &s = cell_tets[t + 3];
    const double six = (q - p).dot((r - p).cross(s - p));
    if (six == 0) continue;
    const std::array<Eigen::Vector4d, 4> planes = tetrahedron_planes(p, q, r, s);
    const Eigen::Vector3d clo = p.cwiseMin(q).cwiseMin(r.cwiseMin(s)), chi = p.cwiseMax(q).cwiseMax(r.cwiseMax(s));
    double part = 0;
    for_each_particle_tetrahedron(m, [&](const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                         const Eigen::Vector3d& c) {
      if (!boxes_meet(clo, chi, o.cwiseMin(a).cwiseMin(b.cwiseMin(c)), o.cwiseMax(a).cwiseMax(b.cwiseMax(c)))) return;
      part += tetrahedron_halfspaces_overlap(o, a, b, c, planes);
    });
    v += six > 0 ? part : -part;
  }
  return v;
}

double mesh_polyhedron_overlap(const PlacedMesh& m, std::span<const Eigen::Vector3d> vertices,
                               std::span<const std::int32_t> face_offsets,
                               std::span<const std::int32_t> face_vertices) {
  double v = 0;
  for_each_face_tetrahedron(vertices, face_offsets, face_vertices,
                            [&](const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& r,
                                const Eigen::Vector3d& s) {
                              const std::array<Eigen::Vector3d, 4> tet{p, q, r, s};
                              v += mesh_polyhedron_overlap(m, tet);
                            });
  return v;
}

}  // namespace vfe::kernels

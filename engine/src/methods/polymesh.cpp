// direct and pmm on an OpenFOAM polyMesh: point location by the cell locator (spatial
// hash for the particle's centre, neighbour walk from there for its sub-elements); the
// fast path and outside policy that exact shares.
#include "methods/polymesh.hpp"

namespace vfe::detail {

bool ball_inside_cell(const PolyMesh& mesh, std::int64_t cell, const Eigen::Vector3d& c, double r) {
  if (!mesh.cell_is_convex(cell)) return false;
  for (const std::int64_t f : mesh.cell_faces(cell)) {
    const double sign = mesh.owner(f) == cell ? 1.0 : -1.0;
    const double depth = sign * (mesh.face_centre(f) - c).dot(mesh.face_normal(f));
    if (!(depth > r + mesh.face_warp(f) + mesh.location_tolerance())) return false;
  }
  return true;
}

void outside_poly(const PolyContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
                  std::int64_t centre_cell, bool& flagged) {
  if (!flagged) {
    flagged = true;
    ++s.outside_particles;
  }
  switch (ctx.opts.outside) {
    case Outside::nearest: s.add(ctx.locator->nearest_cell(at), volume); break;
    case Outside::centre: s.add(centre_cell >= 0 ? centre_cell : ctx.locator->nearest_cell(p.centre), volume); break;
    case Outside::drop: s.add(ctx.locator->mesh().cell_count(), volume); break;  // the dropped-volume slot
    case Outside::error: s.first_error = std::min(s.first_error, p.index); break;
  }
}

void polymesh_particle(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate* t,
                       const Eigen::Vector3d& centroid) {
  const std::int64_t centre_cell = ctx.locator->locate(p.centre);
  bool flagged = false;
  const Eigen::Matrix3d rotation = particle_rotation(ctx.opts, p);
  if (!t) {  // direct: everything at the body's centroid
    const Eigen::Vector3d at = p.centre + p.radius * (rotation * centroid);
    const std::int64_t cell = centroid.isZero() ? centre_cell : ctx.locator->locate_from(at, centre_cell);
    ++s.sub_elements;
    if (cell >= 0)
      s.add(cell, p.volume);
    else
      outside_poly(ctx, s, p, p.volume, at, centre_cell, flagged);
    return;
  }
  const std::int64_t n = static_cast<std::int64_t>(t->size());
  s.count_grid(n);
  if (centre_cell >= 0 && ball_inside_cell(ctx.locator->mesh(), centre_cell, p.centre, p.radius * t->reach)) {
    ++s.fast_path;
    s.add(centre_cell, p.volume);
    return;
  }
  s.sub_elements += n;
  const Eigen::Matrix3d transform = rotation * p.radius;
  for (std::size_t q = 0; q < t->size(); ++q) {
    const Eigen::Vector3d x = p.centre + transform * t->points[q];
    const double v = p.volume * t->fractions[q];
    const std::int64_t cell = ctx.locator->locate_from(x, centre_cell);
    if (cell >= 0)
      s.add(cell, v);
    else
      outside_poly(ctx, s, p, v, x, centre_cell, flagged);
  }
}

}  // namespace vfe::detail

// exact on an OpenFOAM polyMesh: the sphere's exact overlap with every cell whose bounds
// reach its box (kernels/sphere_polyhedron_overlap.hpp); what lies beyond the mesh follows
// the outside policy.
#include "methods/polymesh.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>
#include <vfe/kernels/sphere_polyhedron_overlap.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

namespace vfe::detail {

namespace {

/// Appends face f of cell c to s.cell_*: a planar face as its polygon, a warped one as the
/// fan (apex, P_i, P_i+1).
void append_face(const PolyMesh& mesh, std::int64_t c, std::int64_t f, Scratch& s) {
  const auto close_face = [&] { s.cell_face_offsets.push_back(static_cast<std::int32_t>(s.cell_face_points.size())); };
  const auto face = mesh.face(f);
  const auto n = static_cast<std::int32_t>(face.size());
  const auto first = static_cast<std::int32_t>(s.cell_points.size());
  for (const std::int64_t q : face) s.cell_points.push_back(mesh.points()[static_cast<std::size_t>(q)]);
  // The points' right-hand normal points out of the owner: the neighbour takes them reversed.
  const bool owned = mesh.owner(f) == c;
  const auto point = [&](std::int32_t i) { return first + (owned ? i : n - 1 - i); };
  if (mesh.face_plane_triangle(f) >= 0) {
    for (std::int32_t i = 0; i < n; ++i) s.cell_face_points.push_back(point(i));
    close_face();
  } else {
    const auto apex = static_cast<std::int32_t>(s.cell_points.size());
    s.cell_points.push_back(mesh.face_apex(f));
    for (std::int32_t i = 0; i < n; ++i) {
      s.cell_face_points.insert(s.cell_face_points.end(), {apex, point(i), point(i + 1 == n ? 0 : i + 1)});
      close_face();
    }
  }
}

/// Face f's term of the located sum (kernels::sphere_face_located_term) in its owner's
/// orientation for the particle s.poly_particle, computed on its first use: a warped
/// face as its fan (apex, P_i, P_i+1), as cell_boundary gives it.
const Scratch::FaceTerm& face_term(const PolyMesh& mesh, std::int64_t f, const Eigen::Vector3d& centre,
                                   double radius, Scratch& s) {
  Scratch::FaceTerm& term = s.face_terms[static_cast<std::size_t>(f)];
  if (term.particle == s.poly_particle) return term;
  term = {s.poly_particle, 0.0, true};
  auto& points = s.cell_points;
  points.clear();
  for (const std::int64_t q : mesh.face(f)) points.push_back(mesh.points()[static_cast<std::size_t>(q)]);
  const std::optional<double> v = mesh.face_plane_triangle(f) >= 0
                                      ? kernels::sphere_face_located_term(centre, radius, points)
                                      : kernels::sphere_fan_located_term(centre, radius, mesh.face_apex(f), points);
  term.sure = v.has_value();
  term.value = v.value_or(0.0);
  return term;
}

/// Cell c's overlap by the located sum over its faces that may reach into the ball (a
/// face whose plane lies farther from the centre than the radius and the face's warp,
/// beyond rounding, is left out), each face's term shared with the cell across it; no
/// value where a reaching face's term has none.
std::optional<double> located_cell_overlap(const PolyMesh& mesh, std::int64_t c, const Eigen::Vector3d& centre,
                                           double radius, bool centre_inside, Scratch& s) {
  const double reach = radius + mesh.location_tolerance();
  double sum = 0;
  for (const std::int64_t f : mesh.cell_faces(c)) {
    if (!face_plane_in_reach(mesh, f, centre, reach)) continue;
    const Scratch::FaceTerm& term = face_term(mesh, f, centre, radius, s);
    if (!term.sure) return std::nullopt;
    sum += mesh.owner(f) == c ? term.value : -term.value;
  }
  return kernels::sphere_located_overlap(radius, centre_inside, sum);
}

void clear_boundary(Scratch& s) {
  s.cell_points.clear();
  s.cell_face_points.clear();
  s.cell_face_offsets.assign(1, 0);
}

}  // namespace

/// Both cells of a face thus see the same surface (the point-location one), and their
/// overlaps add up to that of their union.
void cell_boundary(const PolyMesh& mesh, std::int64_t c, Scratch& s) {
  clear_boundary(s);
  for (const std::int64_t f : mesh.cell_faces(c)) append_face(mesh, c, f, s);
}

namespace {

/// A new particle number for s.face_terms and s.cell_particle (sized for the mesh here):
/// what they hold for earlier particles is stale from then on.
std::uint64_t next_particle(const PolyMesh& mesh, Scratch& s) {
  if (s.face_terms.size() != static_cast<std::size_t>(mesh.face_count()))
    s.face_terms.assign(static_cast<std::size_t>(mesh.face_count()), Scratch::FaceTerm{0, 0.0, true});
  if (s.cell_particle.size() != static_cast<std::size_t>(mesh.cell_count()))
    s.cell_particle.assign(static_cast<std::size_t>(mesh.cell_count()), 0);
  return ++s.poly_particle;
}

}  // namespace

bool walk_ball_cells(const PolyMesh& mesh, Scratch& s, const Eigen::Vector3d& centre, double radius,
                     std::int64_t centre_cell, std::uint64_t& particle) {
  particle = next_particle(mesh, s);
  auto& queue = s.candidate_cells;
  queue.assign(1, centre_cell);
  s.cell_particle[static_cast<std::size_t>(centre_cell)] = particle;
  const double reach = radius + mesh.location_tolerance(), r2 = radius * radius;
  bool complete = true;
  for (std::size_t i = 0; i < queue.size(); ++i) {
    const std::int64_t cell = queue[i];
    for (const std::int64_t f : mesh.cell_faces(cell)) {
      if (!face_plane_in_reach(mesh, f, centre, reach)) continue;
      const std::int64_t next = mesh.across(f, cell);
      if (next < 0) {
        complete = false;
        continue;
      }
      std::uint64_t& mark = s.cell_particle[static_cast<std::size_t>(next)];
      if (mark == particle || mesh.cell_bounds(next).squaredExteriorDistance(centre) >= r2) continue;
      mark = particle;
      queue.push_back(next);
    }
  }
  return complete;
}

void polymesh_exact(const PolyContext& ctx, Scratch& s, const Particle& p) {
  polymesh_exact_at(ctx, s, p, ctx.locator->locate(p.centre));
}

void polymesh_exact_at(const PolyContext& ctx, Scratch& s, const Particle& p, std::int64_t centre_cell,
                       std::uint64_t walked) {
  const PolyMesh& mesh = ctx.locator->mesh();
  const Eigen::Vector3d& c = p.centre;
  const double r = p.radius, r2 = r * r;
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, c, r)) {
    ++s.fast_path;
    s.add(centre_cell, p.volume);
    return;
  }
  double inside = 0;
  const bool located = mesh.inverted_tet_count() == 0;
  // Cell `cell`'s overlap into the deposits.
  const auto take = [&](std::int64_t cell) {
    ++s.sub_elements;
    const Eigen::AlignedBox3d& box = mesh.cell_bounds(cell);
    // A cell inside the ball gives its volume (OpenFOAM's, the volume of the same surface).
    const bool contained = (box.min() - c).cwiseAbs().cwiseMax((box.max() - c).cwiseAbs()).squaredNorm() <= r2;
    double v;
    Eigen::AlignedBox3d cell_box;
    if (contained) {
      v = mesh.cell_volume(cell);
    } else if (cached_cell_is_box(mesh, s, cell, cell_box)) {  // the grids' closed form
      v = kernels::sphere_box_overlap(c, r, cell_box.min(), cell_box.max());
    } else {
      // Point location is exact on the same surface: it tells whether the centre is inside
      // (not where some tetrahedra are inverted: their union is not the bounded region).
      std::optional<double> located_volume;
      if (located) located_volume = located_cell_overlap(mesh, cell, c, r, cell == centre_cell, s);
      if (located_volume) {
        ++s.located_cells;
        v = std::min(*located_volume, mesh.cell_volume(cell));
      } else {  // a centre near a reaching face's plane or edge: the whole surface
        ++s.general_cells;
        cell_boundary(mesh, cell, s);
        v = kernels::sphere_polyhedron_overlap(c, r, s.cell_points, s.cell_face_offsets, s.cell_face_points);
      }
    }
    if (v > 0) {
      s.deposits.push_back({cell, v});  // each cell is taken once: no merge needed
      inside += v;
    }
  };
  // The cells the walk finds from the centre's cell; the hash's cells whose bounds reach
  // the ball's box as well where the walk may have missed some (a boundary face in reach,
  // or volume missing beyond round-off).
  std::uint64_t particle = walked;
  bool search = centre_cell < 0;
  if (!search) {
    if (walked == 0) search = !walk_ball_cells(mesh, s, c, r, centre_cell, particle);
    for (const std::int64_t cell : s.candidate_cells) take(cell);
    search = search || p.volume - inside > 1e-12 * p.volume;
  } else {
    particle = next_particle(mesh, s);
  }
  if (search) {
    const Eigen::Vector3d half = Eigen::Vector3d::Constant(r);
    ctx.locator->hash().cells_in_box(Eigen::AlignedBox3d(c - half, c + half), s.candidate_cells);
    for (const std::int64_t cell : s.candidate_cells)
      if (s.cell_particle[static_cast<std::size_t>(cell)] != particle &&
          mesh.cell_bounds(cell).squaredExteriorDistance(c) < r2)
        take(cell);
  }
  // What the cells do not hold lies beyond the mesh (beyond round-off).
  const double rest = p.volume - inside;
  bool flagged = false;
  if (rest > 1e-12 * p.volume) outside_poly(ctx, s, p, rest, c, centre_cell, flagged, p.outside);
}

}  // namespace vfe::detail

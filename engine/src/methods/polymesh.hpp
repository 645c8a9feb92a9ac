// The drivers of direct, pmm and exact on an OpenFOAM polyMesh.
#pragma once

#include "methods/driver.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"

#include <cmath>

namespace vfe::detail {

struct PolyContext : MethodContext {
  const CellLocator* locator;
};

/// True when the ball (c, r) lies inside cell `cell`: deeper than r plus the warp below
/// every face plane. Sufficient for the fast path (a cell that is not convex answers no).
bool ball_inside_cell(const PolyMesh& mesh, std::int64_t cell, const Eigen::Vector3d& c, double r);

/// Volume of particle p that lies outside the mesh, handled by `policy`: `nearest` gives it
/// to the cell with the centre nearest to `at`, `centre` to centre_cell (or the cell nearest
/// to p's centre when that is -1); flagged counts the particle once.
void outside_poly(const PolyContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
                  std::int64_t centre_cell, bool& flagged, Outside policy);

/// A ball of a template's tree (kernels::PointTree) is tested against the cell holding its
/// centre only below this many points: larger ones almost never lie in one cell
/// (docs/performance.md, "pmm on a polyMesh: balls of template points held whole").
inline constexpr std::uint32_t kMostPointsTested = 256;

/// Deposits every point of template t (scaled by p.radius, rotated) into the cell that
/// CellLocator::locate_from (and nearest_cell) would give it, found per particle from the
/// cells near it (docs/polymesh.md, "How pmm locates sub-elements on a polyMesh"); outside
/// points follow `policy`. centre_cell: the cell holding p's centre, or -1.
void polymesh_points(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                     const Eigen::Matrix3d& rotation, Outside policy, std::int64_t centre_cell);

/// Cell c's boundary as outward polygons into s.cell_points / cell_face_offsets /
/// cell_face_points: a planar face as its polygon, a warped one as the fan (apex, P_i,
/// P_i+1). Both cells of a face see the same surface (the point-location one), so their
/// overlaps with any body add up to that of their union.
void cell_boundary(const PolyMesh& mesh, std::int64_t c, Scratch& s);

/// True when cell c is an axis-aligned box (convex, every face in one of the six planes of
/// its points' box); then box holds it.
bool cell_is_box(const PolyMesh& mesh, std::int64_t c, Eigen::AlignedBox3d& box);
/// cell_is_box, answered once per cell and thread (s.poly_box_corners).
bool cached_cell_is_box(const PolyMesh& mesh, Scratch& s, std::int64_t c, Eigen::AlignedBox3d& box);

// The methods on a polyMesh: s gets the particle's deposits.
void polymesh_direct(const PolyContext& ctx, Scratch& s, const Particle& p);
void polymesh_pmm(const PolyContext& ctx, Scratch& s, const Particle& p);
void polymesh_divided(const PolyContext& ctx, Scratch& s, const Particle& p);
void polymesh_big_particle(const PolyContext& ctx, Scratch& s, const Particle& p);
void polymesh_gaussian(const PolyContext& ctx, Scratch& s, const Particle& p);
void polymesh_porous_cube(const PolyContext& ctx, Scratch& s, const Particle& p);

/// exact on a polyMesh: the exact overlap volume of sphere p with every cell it reaches,
/// each cell bounded by its faces: a planar face as its polygon, a warped one as the fan
/// of triangles (face apex, two consecutive points), the surface of the point-in-cell
/// test; what lies beyond the mesh follows the outside policy.
void polymesh_exact(const PolyContext& ctx, Scratch& s, const Particle& p);

/// polymesh_pmm and polymesh_exact for a sphere whose centre's cell is known (centre_cell;
/// -1 outside the mesh): method=auto has located it. walked: s.candidate_cells already
/// holds what walk_ball_cells found for this sphere, and it found every cell (it returned
/// true; particle: the number it gave), so exact need not walk again.
void polymesh_pmm_at(const PolyContext& ctx, Scratch& s, const Particle& p, std::int64_t centre_cell);
void polymesh_exact_at(const PolyContext& ctx, Scratch& s, const Particle& p, std::int64_t centre_cell,
                       std::uint64_t walked = 0);

/// Whether face f's plane may reach into the ball about centre: it lies no farther than
/// reach (the radius and the location tolerance) plus the face's warp. A face beyond can
/// neither cut the ball nor lead a walk to a cell the ball overlaps.
inline bool face_plane_in_reach(const PolyMesh& mesh, std::int64_t f, const Eigen::Vector3d& centre, double reach) {
  return !(std::fabs(mesh.face_normal(f).dot(centre - mesh.face_centre(f))) > reach + mesh.face_warp(f));
}

/// The cells whose bounds reach the ball (centre, radius) that a walk finds from
/// centre_cell (>= 0) across the faces whose planes the ball reaches, into
/// s.candidate_cells, each marked in s.cell_particle with a new particle number (returned
/// in `particle`; s.face_terms share it). The part of the ball in the mesh is connected when
/// no boundary face reaches into it, and then the walk finds every cell that overlaps the
/// ball: returns false when a boundary face is in reach (the mesh's edge, or a baffle that
/// may cut the ball), where the cells beyond it may be missing.
bool walk_ball_cells(const PolyMesh& mesh, Scratch& s, const Eigen::Vector3d& centre, double radius,
                     std::int64_t centre_cell, std::uint64_t& particle);

}  // namespace vfe::detail

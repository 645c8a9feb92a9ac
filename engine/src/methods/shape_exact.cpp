// exact for ellipsoids and triangle-mesh particles on every mesh kind: the body placed by
// centre + scale * rotation * (template point), its exact overlap with each cell its
// bounding box reaches (box cells by the box forms, other polyMesh cells by their faces);
// what lies beyond the mesh follows the outside policy.
#include "methods/shape_exact.hpp"

#include <vfe/kernels/ellipsoid_overlap.hpp>
#include <vfe/kernels/mesh_overlap.hpp>

#include <algorithm>
#include <cmath>
#include <span>

namespace vfe::detail {

namespace {

/// A remainder below this share of the particle's volume is the round-off of summing many
/// clipped pieces (a few 1e-14 in the kernels' tests), not volume beyond the mesh: the
/// deposits are rescaled to the particle's volume instead.
constexpr double kRoundOff = 1e-10;

/// One particle's body in space: the ellipsoid or the placed mesh, its bounding box and the
/// radius of a ball about the particle's centre that holds it.
struct PlacedBody {
  bool ellipsoid = false;
  kernels::Ellipsoid e;
  kernels::PlacedMesh m;
  Eigen::AlignedBox3d box;
  double reach = 0;

  double box_overlap(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) const {
    if (!box.intersects(Eigen::AlignedBox3d(lo, hi))) return 0;
    return ellipsoid ? kernels::ellipsoid_box_overlap(e, lo, hi) : kernels::mesh_box_overlap(m, lo, hi);
  }

  /// Overlap with the cell whose boundary cell_boundary put into s.
  double faces_overlap(Scratch& s) const {
    if (!ellipsoid) return kernels::mesh_polyhedron_overlap(m, s.cell_points, s.cell_face_offsets, s.cell_face_points);
    s.mapped_points.resize(s.cell_points.size());
    return kernels::ellipsoid_polyhedron_overlap(e, s.cell_points, s.cell_face_offsets, s.cell_face_points,
                                                 s.mapped_points);
  }
};

PlacedBody place(const Options& opts, const Particle& p) {
  const Eigen::Matrix3d rotation = particle_rotation(opts, p);
  const kernels::Shape& shape = *p.shape;
  PlacedBody b;
  if (shape.kind() == kernels::Shape::Kind::ellipsoid) {
    b.ellipsoid = true;
    b.e.centre = p.centre;
    b.e.semi_axes = p.radius * shape.axes();
    b.e.rotation = rotation;
    // The extent along axis d of {R D y : |y| <= 1} is the norm of row d of R D.
    const Eigen::Vector3d half = (rotation * b.e.semi_axes.asDiagonal()).rowwise().norm();
    b.box = Eigen::AlignedBox3d(p.centre - half, p.centre + half);
    b.reach = b.e.semi_axes.maxCoeff();
    return b;
  }
  b.m.mesh = &shape.mesh();
  b.m.translation = p.centre;
  b.m.linear = rotation * p.radius;
  b.box = Eigen::AlignedBox3d(p.centre, p.centre);
  for (const Eigen::Vector3d& v : shape.mesh().vertices) {
    b.box.extend(Eigen::Vector3d(p.centre + b.m.linear * v));
    b.reach = std::max(b.reach, p.radius * v.norm());
  }
  return b;
}

/// The overlaps with the cells of a box grid's block lo..hi (per axis, inclusive):
/// node(d, g) is the coordinate of node g on axis d, cell(i, j, k) the mesh cell of block
/// cell (lo + (i, j, k)). Returns the volume deposited.
template <class Node, class Cell>
double block_overlaps(const PlacedBody& b, Scratch& s, const std::int64_t lo[3], const std::int64_t hi[3],
                      Node&& node, Cell&& cell) {
  double inside = 0;
  for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
    for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
      for (std::int64_t i = lo[0]; i <= hi[0]; ++i) {
        const double v = b.box_overlap(Eigen::Vector3d(node(0, i), node(1, j), node(2, k)),
                                       Eigen::Vector3d(node(0, i + 1), node(1, j + 1), node(2, k + 1)));
        if (v <= 0) continue;
        s.add(cell(i, j, k), v);
        inside += v;
      }
  s.sub_elements += (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
  return inside;
}

/// The volume the cells did not take: beyond the mesh (to `beyond`, the outside policy)
/// when the body reaches out and it is more than round-off; otherwise the deposits are
/// rescaled so they sum to the particle's volume.
template <class Beyond>
void settle(Scratch& s, const Particle& p, double inside, bool reaches_out, Beyond&& beyond) {
  const double rest = p.volume - inside;
  if (reaches_out && rest > kRoundOff * p.volume) {
    beyond(rest);
  } else if (inside > 0) {
    const double scale = p.volume / inside;
    for (Deposit& d : s.deposits) d.volume *= scale;
  }
}

void check_block(const Particle& p, const std::int64_t lo[3], const std::int64_t hi[3]) {
  if (double(hi[0] - lo[0] + 1) * double(hi[1] - lo[1] + 1) * double(hi[2] - lo[2] + 1) > double(1 << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(p.index) +
                                                " overlaps more than 2^26 cells; use cells no smaller than about "
                                                "1/400 of the particle size");
}

}  // namespace

std::string exact_shape_refusal(const kernels::Shape& shape, std::int32_t id) {
  using Kind = kernels::Shape::Kind;
  if (shape.kind() == Kind::sphere || shape.kind() == Kind::ellipsoid || shape.kind() == Kind::mesh) return "";
  return "method=exact computes spheres, ellipsoids and triangle meshes, but shape " + std::to_string(id) +
         " is a " + shape.description() +
         " (no exact overlap with a cell); use method=pmm (a large particle_grid, e.g. 20000, serves as the "
         "reference)";
}

void exact_any_particle(const Context& ctx, Scratch& s, const Particle& p) {
  if (!p.shaped) return exact_particle(ctx, s, p);
  const CartesianGrid& grid = ctx.grid;
  const PlacedBody b = place(ctx.opts, p);
  if (const std::int64_t cell = single_cell(ctx, b.box.center(), 0.5 * b.box.sizes()); cell >= 0) {
    ++s.fast_path;
    s.add(cell, p.volume);
    return;
  }
  std::int64_t lo[3], hi[3];
  bool empty = false, reaches_out = false;
  for (int d = 0; d < 3; ++d) {
    lo[d] = grid.axis_index(d, b.box.min()[d]);
    hi[d] = grid.axis_index(d, b.box.max()[d]);
    if (grid.periodic(d)) continue;  // cells beyond the side wrap (cell_axis below)
    reaches_out |= lo[d] < 0 || hi[d] >= grid.cells()[d] || b.box.max()[d] >= grid.upper()[d];
    lo[d] = std::max<std::int64_t>(lo[d], 0);
    hi[d] = std::min<std::int64_t>(hi[d], grid.cells()[d] - 1);
    empty |= lo[d] > hi[d];
  }
  bool flagged = false;
  const auto beyond = [&](double v) { outside(ctx, s, p, v, grid.nearest(p.centre), flagged, p.outside); };
  if (empty) return beyond(p.volume);
  check_block(p, lo, hi);
  const double inside = block_overlaps(
      b, s, lo, hi, [&](int d, std::int64_t g) { return grid.node(d, g); },
      [&](std::int64_t i, std::int64_t j, std::int64_t k) {
        return grid.index(grid.cell_axis(0, i), grid.cell_axis(1, j), grid.cell_axis(2, k));
      });
  settle(s, p, inside, reaches_out, beyond);
}

void rectilinear_exact_any(const RectilinearContext& ctx, Scratch& s, const Particle& p) {
  if (!p.shaped) return rectilinear_exact(ctx, s, p);
  const RectilinearGrid& grid = ctx.grid;
  const PlacedBody b = place(ctx.opts, p);
  const auto periodic = [&](int d) { return ((ctx.opts.periodic >> d) & 1u) != 0; };
  std::int64_t lo[3], hi[3];
  bool empty = false, reaches_out = false;
  for (int d = 0; d < 3; ++d) {
    if (periodic(d)) {
      lo[d] = periodic_axis_index(grid, d, b.box.min()[d]);
      hi[d] = periodic_axis_index(grid, d, b.box.max()[d]);
      continue;
    }
    reaches_out |= b.box.min()[d] < grid.nodes(d).front() || b.box.max()[d] >= grid.nodes(d).back();
    lo[d] = std::max<std::int64_t>(grid.axis_index(d, b.box.min()[d]), 0);
    hi[d] = std::min<std::int64_t>(grid.axis_index(d, b.box.max()[d]), grid.cells()[d] - 1);
    empty |= lo[d] > hi[d];
  }
  bool flagged = false;
  const auto beyond = [&](double v) {
    apply_outside(s, p, v, p.outside, grid.cell_count(), flagged, [&] { return grid.nearest(p.centre); },
                  [&] { return grid.nearest(p.centre); });
  };
  if (empty) return beyond(p.volume);
  check_block(p, lo, hi);
  if (ctx.opts.fast_path && lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2] && !reaches_out) {
    ++s.fast_path;
    s.add(grid.index(lo[0], lo[1], lo[2]), p.volume);
    return;
  }
  const auto wrap = [&](int d, std::int64_t g) {
    const std::int64_t n = grid.cells()[d];
    return ((g % n) + n) % n;
  };
  const double inside = block_overlaps(
      b, s, lo, hi, [&](int d, std::int64_t g) { return periodic_node(grid, d, g); },
      [&](std::int64_t i, std::int64_t j, std::int64_t k) { return grid.index(wrap(0, i), wrap(1, j), wrap(2, k)); });
  settle(s, p, inside, reaches_out, beyond);
}

void polymesh_exact_any(const PolyContext& ctx, Scratch& s, const Particle& p) {
  if (!p.shaped) return polymesh_exact(ctx, s, p);
  const PolyMesh& mesh = ctx.locator->mesh();
  const PlacedBody b = place(ctx.opts, p);
  const std::int64_t centre_cell = ctx.locator->locate(p.centre);
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, p.centre, b.reach)) {
    ++s.fast_path;
    s.add(centre_cell, p.volume);
    return;
  }
  ctx.locator->hash().cells_in_box(b.box, s.candidate_cells);
  s.sub_elements += static_cast<std::int64_t>(s.candidate_cells.size());
  double inside = 0;
  for (const std::int64_t cell : s.candidate_cells) {
    if (!mesh.cell_bounds(cell).intersects(b.box)) continue;
    Eigen::AlignedBox3d box;
    double v;
    if (cell_is_box(mesh, cell, box)) {
      v = b.box_overlap(box.min(), box.max());
    } else {
      cell_boundary(mesh, cell, s);
      v = b.faces_overlap(s);
    }
    if (v > 0) {
      s.deposits.push_back({cell, v});  // candidates are distinct: no merge needed
      inside += v;
    }
  }
  // Whether the body reaches beyond the mesh is known only from what the cells hold.
  bool flagged = false;
  settle(s, p, inside, true, [&](double v) { outside_poly(ctx, s, p, v, p.centre, centre_cell, flagged, p.outside); });
}

}  // namespace vfe::detail

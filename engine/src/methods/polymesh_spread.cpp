// gaussian and porous_cube on a polyMesh: the kernel's share of every cell that its box
// reaches. A cell that is an axis-aligned box gets the separable closed form (the Cartesian
// grid's weights); any other cell the kernel's integral over the cell bounded by its faces
// (the surface of point location, so neighbours share each face): porous_cube's cube-cell
// overlap exactly (signed tetrahedra clipped to the cube, kernels/polytope.hpp), gaussian's
// to kernels::kGaussianCellTolerance per cell (kernels/gaussian_polyhedron.hpp). What the
// cells do not hold lies beyond the mesh and follows the outside policy.
#include "methods/polymesh.hpp"

#include <vfe/kernels/gaussian.hpp>
#include <vfe/kernels/gaussian_polyhedron.hpp>
#include <vfe/kernels/polytope.hpp>

#include <algorithm>
#include <cmath>

namespace vfe::detail {

namespace {

/// The kernel of half-width `half` around p's centre: box_share(cell box) for box cells,
/// cell_share(cell) (its faces in s.cell_*) for the others; both are fractions of 1.
template <class BoxShare, class CellShare>
void spread(const PolyContext& ctx, Scratch& s, const Particle& p, double half, BoxShare&& box_share,
            CellShare&& cell_share) {
  const PolyMesh& mesh = ctx.locator->mesh();
  const Eigen::Vector3d& c = p.centre;
  const std::int64_t centre_cell = ctx.locator->locate(c);
  // The kernel's box lies in the centre's cell when the ball around the box does.
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, c, half * std::sqrt(3.0))) {
    ++s.fast_path;
    s.add(centre_cell, p.volume);
    return;
  }
  const Eigen::AlignedBox3d kernel_box(c - Eigen::Vector3d::Constant(half), c + Eigen::Vector3d::Constant(half));
  ctx.locator->hash().cells_in_box(kernel_box, s.candidate_cells);
  s.sub_elements += static_cast<std::int64_t>(s.candidate_cells.size());
  double inside = 0;
  for (const std::int64_t cell : s.candidate_cells) {
    if (!mesh.cell_bounds(cell).intersects(kernel_box)) continue;
    Eigen::AlignedBox3d box;
    double w;
    if (cached_cell_is_box(mesh, s, cell, box)) {
      w = box_share(box);
    } else {
      cell_boundary(mesh, cell, s);
      w = cell_share(s);
    }
    if (w > 0) {
      s.deposits.push_back({cell, w * p.volume});  // candidates are distinct: no merge needed
      inside += w;
    }
  }
  const double rest = 1.0 - inside;
  bool flagged = false;
  if (rest > 1e-12) {
    outside_poly(ctx, s, p, rest * p.volume, c, centre_cell, flagged, p.outside);
  } else if (inside > 0) {
    // Within rounding (and gaussian's quadrature tolerance) of the whole kernel: make the
    // shares sum to the particle's volume exactly.
    for (Deposit& d : s.deposits) d.volume /= inside;
  }
}

}  // namespace

void polymesh_porous_cube(const PolyContext& ctx, Scratch& s, const Particle& p) {
  const double half = ctx.opts.gamma * p.radius;
  const Eigen::Vector3d lo = p.centre - Eigen::Vector3d::Constant(half), hi = p.centre + Eigen::Vector3d::Constant(half);
  const double cube = 8 * half * half * half;
  spread(
      ctx, s, p, half,
      [&](const Eigen::AlignedBox3d& box) {
        double w = 1;
        for (int d = 0; d < 3; ++d)
          w *= std::max(0.0, std::min(hi[d], box.max()[d]) - std::max(lo[d], box.min()[d])) / (2 * half);
        return w;
      },
      [&](const Scratch& sc) {
        return kernels::box_polyhedron_overlap(lo, hi, sc.cell_points, sc.cell_face_offsets, sc.cell_face_points) / cube;
      });
}

void polymesh_gaussian(const PolyContext& ctx, Scratch& s, const Particle& p) {
  const double sigma = ctx.opts.sigma * 2.0 * p.radius;
  const double cut = kernels::kGaussianCut * sigma;
  spread(
      ctx, s, p, cut,
      [&](const Eigen::AlignedBox3d& box) {
        // Per axis the cut normal's mass in the cell's interval over its mass in the cut
        // interval (gaussian_axis_weights' closed form, for one cell of many).
        const double k = 1.0 / (std::sqrt(2.0) * sigma), total = 2 * std::erf(kernels::kGaussianCut / std::sqrt(2.0));
        double w = 1;
        for (int d = 0; d < 3; ++d) {
          const double a = p.centre[d] - cut, b = p.centre[d] + cut;
          const double part = std::erf((std::clamp(box.max()[d], a, b) - p.centre[d]) * k) -
                              std::erf((std::clamp(box.min()[d], a, b) - p.centre[d]) * k);
          w *= std::max(part, 0.0) / total;
        }
        return w;
      },
      [&](const Scratch& sc) {
        return kernels::gaussian_polyhedron_integral(p.centre, sigma, sc.cell_points, sc.cell_face_offsets,
                                                     sc.cell_face_points);
      });
}

}  // namespace vfe::detail

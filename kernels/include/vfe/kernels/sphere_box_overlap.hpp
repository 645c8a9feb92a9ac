// Exact overlap volume of a sphere with axis-aligned boxes and rectilinear cell patches.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace vfe::kernels {

/// Volume of the unit ball intersected with the orthant {X <= x, Y <= y, Z <= z}.
/// Exact to round-off for every finite (x, y, z), infinities allowed (meaning "no bound");
/// arguments are clamped to [-1, 1], so x <= -1 gives exactly 0 and x, y, z >= 1 gives
/// exactly 4 pi / 3.  Closed form (no quadrature); NaN in, NaN out.
double unit_ball_orthant_volume(double x, double y, double z);

/// The unit ball cut by the planes X = a, Y = b, Z = c into 8 parts: volumes[i + 2j + 4k]
/// is the part on the upper side of the X plane when i = 1 (lower side when 0), likewise j
/// for Y and b, k for Z and c.  A plane with |t| >= 1 (infinities allowed: "no plane")
/// misses the ball and leaves its far side exactly 0; so do parts the ball does not reach
/// (tangent included).  Exact to round-off (absolute error ~1e-15 of the ball volume), the
/// parts summing to 4 pi / 3 to round-off; a part cut off by one plane alone is the cap
/// formula's value.  Costs 3 caps, 3 wedges and one corner in closed form (9 angles, 3 square
/// roots) when all three planes cut, one wedge for two, a cap for one: the cells of a sphere
/// spanning at most 2 cells per axis, in one call.
void unit_ball_octants(double a, double b, double c, double volumes[8]);

/// Volume of the ball |p - centre| <= radius intersected with the box [lo, hi].
/// Exact to round-off (absolute error ~1e-15 of the ball volume); exactly 0 when the
/// box does not reach into the ball (tangent included), exactly the box volume when the
/// box lies inside the ball, exactly the ball volume when the ball lies inside the box;
/// 0 for radius <= 0 or a box that is empty or flat (lo >= hi on some axis).
double sphere_box_overlap(const Eigen::Vector3d& centre, double radius,
                          const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Exact overlaps of one sphere with the cells of a rectilinear patch.
/// The patch has node coordinates x[0..nx], y[0..ny], z[0..nz] (strictly increasing),
/// so nx*ny*nz cells; cell (i, j, k) is [x[i], x[i+1]] x [y[j], y[j+1]] x [z[k], z[k+1]].
/// Resizes volumes_out to nx*ny*nz and stores the overlap of cell (i, j, k) at index
/// i + nx*(j + ny*k): exactly 0 for cells the ball does not reach (tangent included),
/// exactly the cell volume for cells inside the ball, exactly the ball volume for a cell
/// holding the ball, otherwise the 8-corner difference of the orthant volumes at the
/// cell's nodes (each node evaluated once), clamped to [0, cell volume].  `scratch` holds
/// the node values and per-axis tables; neither vector is reallocated once it has enough
/// capacity.
/// The volumes sum to the part of the ball inside the patch, to round-off, and agree
/// with sphere_box_overlap on each cell to round-off.
void sphere_patch_overlaps_into(const Eigen::Vector3d& centre, double radius,
                                const double* x, int nx, const double* y, int ny,
                                const double* z, int nz, std::vector<double>& scratch,
                                std::vector<double>& volumes_out);

/// As sphere_patch_overlaps_into, then calls sink(i, j, k, volume) once for every cell
/// with a positive overlap, in i-fastest order.
template <class Sink>
void sphere_patch_overlaps(const Eigen::Vector3d& centre, double radius, const double* x, int nx,
                           const double* y, int ny, const double* z, int nz,
                           std::vector<double>& scratch, std::vector<double>& volumes,
                           Sink&& sink) {
  sphere_patch_overlaps_into(centre, radius, x, nx, y, ny, z, nz, scratch, volumes);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const double v = volumes[static_cast<std::size_t>(i + nx * (j + ny * k))];
        if (v > 0.0) sink(i, j, k, v);
      }
}

}  // namespace vfe::kernels

// Every method on a rectilinear (graded Cartesian) grid: per-axis binary search to locate,
// windows of cells with the grid's own nodes (continued past the ends on periodic axes),
// closed-form sphere-box overlaps for exact and the separable kernels' closed forms for
// gaussian and porous_cube.
#pragma once

#include "methods/driver.hpp"
#include "polymesh/rectilinear_grid.hpp"

namespace vfe::detail {

struct RectilinearContext : MethodContext {
  const RectilinearGrid& grid;
};

void rectilinear_direct(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_pmm(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_exact(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_divided(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_gaussian(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_porous_cube(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_big_particle(const RectilinearContext& ctx, Scratch& s, const Particle& p);
void rectilinear_trilinear(const RectilinearContext& ctx, Scratch& s, const Particle& p);

/// The one cell wholly holding the box c +- half, or -1 (always -1 with fast_path=0).
std::int64_t rectilinear_one_cell(const RectilinearContext& ctx, const Eigen::Vector3d& c, const Eigen::Vector3d& half);

/// A ball's box of cells, located once for exact and method=auto's model: per axis the cells
/// of c - r and c + r (continued periodically on a periodic axis, else as axis_index gives
/// them: -1 below the grid, n above), and the one cell holding the whole ball where there
/// is one (rectilinear_one_cell's answer).
struct BallBox {
  std::int64_t lo[3], hi[3];
  std::int64_t one_cell = -1;
};
BallBox ball_box(const RectilinearContext& ctx, const Eigen::Vector3d& c, double r);

/// rectilinear_exact for a ball whose box is known and not in one cell.
void rectilinear_exact_in_box(const RectilinearContext& ctx, Scratch& s, const Particle& p, const BallBox& box);

/// Node g of axis d, continued periodically past the ends (g may be < 0 or > n).
double periodic_node(const RectilinearGrid& grid, int d, std::int64_t g);

/// Cell coordinate of x along axis d, continued periodically (may be < 0 or >= n).
std::int64_t periodic_axis_index(const RectilinearGrid& grid, int d, double x);

/// A position moved into the grid along its periodic axes (others unchanged).
Eigen::Vector3d rectilinear_wrap(const RectilinearGrid& grid, unsigned periodic, Eigen::Vector3d x);

}  // namespace vfe::detail

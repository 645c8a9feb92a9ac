// The gaussian method's kernel (gaussian.hpp: a normal density of standard deviation sigma
// around the particle's centre, cut at 3 sigma along each axis and normalised) integrated
// over a polyhedral cell, for meshes whose cells are not boxes.
#pragma once

#include <vfe/kernels/polytope.hpp>

namespace vfe::kernels {

/// Default absolute tolerance on a cell's share of the kernel (whose total is 1). The
/// error estimate is conservative: the errors measured on box cells against the closed
/// form stay below 1e-8 at this setting (test GaussianPolyhedronIntegral prints them);
/// about 150 us per hexahedral cell (24 tetrahedra) overlapping the kernel.
inline constexpr double kGaussianCellTolerance = 1e-6;

/// The cut, normalised Gaussian's mass inside a cell given as signed tetrahedra
/// (TetrahedraView): each tetrahedron is clipped exactly to the cut box
/// [centre - 3 sigma, centre + 3 sigma] (the kernel is 0 outside), then integrated by the
/// degree-5 rule, each piece split into 8 until two levels agree to its share of the
/// tolerance (share = tolerance x its volume / the cut box's volume, at most 6 levels).
/// Error against the exact integral: at most `tolerance` per cell (tested against the
/// separable closed form of gaussian_axis_weights on box and rotated cells); the shares
/// of cells that tile the cut box sum to 1 within tolerance x the number of cells, and
/// exactly (to round-off) the pieces' integrals are additive. sigma > 0; allocation-free.
double gaussian_polyhedron_integral(const Eigen::Vector3d& centre, double sigma, TetrahedraView tets,
                                    double tolerance = kGaussianCellTolerance);

/// The same for a cell given by its faces (for_each_face_tetrahedron's layout).
double gaussian_polyhedron_integral(const Eigen::Vector3d& centre, double sigma,
                                    std::span<const Eigen::Vector3d> vertices,
                                    std::span<const std::int32_t> face_offsets,
                                    std::span<const std::int32_t> face_vertices,
                                    double tolerance = kGaussianCellTolerance);

}  // namespace vfe::kernels

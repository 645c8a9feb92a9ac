// Porous cube (Link et al. 2005, Khawaja 2012): a particle's volume spread uniformly over
// an axis-aligned cube of side gamma * d_p around its centre; each cell gets the particle
// volume times the exact fraction of the cube it overlaps.
#pragma once

#include <vfe/kernels/separable.hpp>

#include <Eigen/Core>

namespace vfe::kernels {

/// Exact overlap volume of the axis-aligned boxes [lo1, hi1] and [lo2, hi2]: the product
/// of the per-axis interval overlaps; 0 when they do not overlap or either box is empty.
double box_box_overlap(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
                       const Eigen::Vector3d& hi2);

/// Weights along one axis: w[i] is the fraction of the interval [a, b] inside the cell
/// [nodes[i], nodes[i+1]], i < m (nodes increase; nodes[0] may be -infinity and nodes[m]
/// +infinity). Normalised to sum 1 (to round-off) when the nodes cover [a, b]. A cube
/// side below round-off (b - a <= 0 relative to the nodes) gives all the weight to the
/// cell holding a, as the direct method would. The product of the three axes' weights is
/// box_box_overlap(cube, cell) / cube volume.
void interval_axis_weights(double a, double b, const double* nodes, int m, double* w);

}  // namespace vfe::kernels

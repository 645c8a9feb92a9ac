// Gaussian kernel spreading (Xiao & Sun 2011 style): a particle's volume spread over the
// cells by a normalised Gaussian of standard deviation sigma around its centre, cut at
// 3 sigma along each axis. Each cell gets the kernel's integral over the cell, so the
// weights vary smoothly with the particle's position at any cell size.
#pragma once

#include <vfe/kernels/separable.hpp>

namespace vfe::kernels {

/// The kernel is cut at this many standard deviations along each axis.
inline constexpr double kGaussianCut = 3.0;

/// Weights along one axis: w[i] is the mass of the normal distribution (centre, sigma),
/// restricted to [centre - 3 sigma, centre + 3 sigma], that lies in the cell
/// [nodes[i], nodes[i+1]], i < m. nodes increase; nodes[0] may be -infinity and nodes[m]
/// +infinity (cells beyond a mesh). The weights are normalised: they sum to 1 (to
/// round-off) when the nodes cover the cut interval; when no cell gets any mass (sigma
/// below round-off), the cell holding the centre gets 1. sigma > 0.
void gaussian_axis_weights(double centre, double sigma, const double* nodes, int m, double* w);

}  // namespace vfe::kernels

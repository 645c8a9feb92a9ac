// CFDEMcoupling's `divided` void fraction: a sphere represented by 29 points of equal
// volume, not rotated with the particle.
#pragma once

#include <vfe/kernels/particle_template.hpp>

#include <Eigen/Core>

#include <array>

namespace vfe::kernels {

/// Radii of the two shells of satellite points, as fractions of the particle radius.
inline constexpr double kDividedInnerShell = 0.623926;
inline constexpr double kDividedOuterShell = 0.917902;
inline constexpr int kDividedPoints = 29;

/// The 14 unit directions of each shell: 6 along the axes (+x, -x, +y, -y, +z, -z), then 8
/// at polar angle 45 and 135 degrees and azimuth 45 + 90 k degrees, i.e.
/// (+-1/2, +-1/2, +-1/sqrt(2)).
const std::array<Eigen::Vector3d, 14>& divided_directions();

/// The 29 points of the unit sphere: the centre, then the 14 directions scaled by the inner
/// shell radius, then by the outer one. Each point carries 1/29 of the volume; family
/// "divided". The layout is fixed (no particle_grid) and must not be rotated.
ParticleTemplate make_divided_template();

}  // namespace vfe::kernels

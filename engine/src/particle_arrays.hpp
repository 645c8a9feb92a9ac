// The host's particle arrays as the engine reads them: pointers with byte strides (an array
// of structs is read in place, nothing is copied), and their validation.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace vfe::detail {

struct ParticleArrays {
  std::int64_t n = 0;
  const char* centres = nullptr;       ///< x, y, z doubles
  std::int64_t centres_stride = 24;    ///< bytes between particles
  const char* radii = nullptr;         ///< radius (the scale for shapes)
  std::int64_t radii_stride = 8;
  const char* orientations = nullptr;  ///< w, x, y, z doubles, or null
  std::int64_t orientations_stride = 32;
  const char* shape_ids = nullptr;     ///< int32, or null (spheres)
  std::int64_t shape_ids_stride = 4;
  const char* ids = nullptr;           ///< int64 host ids, or null
  std::int64_t ids_stride = 8;
  /// int64 index of each particle in the host's arrays, or null (the same order): set
  /// when the engine computes a copy in another order (particle_order.hpp).
  const char* host_index = nullptr;
  std::int64_t host_index_stride = 8;

  Eigen::Vector3d centre(std::int64_t p) const {
    const double* c = reinterpret_cast<const double*>(centres + p * centres_stride);
    return {c[0], c[1], c[2]};
  }
  double radius(std::int64_t p) const { return *reinterpret_cast<const double*>(radii + p * radii_stride); }
  const double* orientation(std::int64_t p) const {
    return orientations ? reinterpret_cast<const double*>(orientations + p * orientations_stride) : nullptr;
  }
  std::int32_t shape_id(std::int64_t p) const {
    return *reinterpret_cast<const std::int32_t*>(shape_ids + p * shape_ids_stride);
  }
  /// The host's index of particle p: what errors, rotations and drivers call it.
  std::int64_t host(std::int64_t p) const {
    return host_index ? *reinterpret_cast<const std::int64_t*>(host_index + p * host_index_stride) : p;
  }
  /// The key of orientation=random: the host's id when given, else the index.
  std::uint64_t rotation_key(std::int64_t p) const {
    return ids ? static_cast<std::uint64_t>(*reinterpret_cast<const std::int64_t*>(ids + p * ids_stride))
               : static_cast<std::uint64_t>(p);
  }
};

/// What validation learns of the particles.
struct Validation {
  std::int64_t first_bad = std::numeric_limits<std::int64_t>::max();
  double volume = 0;  ///< of all particles
  double d_min = std::numeric_limits<double>::infinity(), d_max = 0;  ///< spheres' diameters
  double shape_volume_max = 0;  ///< the largest volume of a particle that is not a sphere
  std::int64_t beyond = 0;  ///< spheres reaching beyond a grid's box by more than outside_tolerance
};

/// The bounds the checks below need before any arithmetic on a particle's values, read
/// from the bits alone: no floating-point operation, so a NaN, an infinity or a value whose
/// cube overflows raises nothing a host traps (OpenFOAM traps invalid operations, division
/// by zero and overflow by default). |x| < bound, a positive finite bound (NaN is not below).
inline bool magnitude_below(double x, double bound) {
  return (std::bit_cast<std::uint64_t>(x) & ~(std::uint64_t(1) << 63)) < std::bit_cast<std::uint64_t>(bound);
}
/// 0 < r < 1e100: a volume of the radius cubed (times a shape's) that doubles hold.
inline bool radius_in_bounds(double r) {
  const auto bits = std::bit_cast<std::int64_t>(r);
  return bits > 0 && bits < std::bit_cast<std::int64_t>(1e100);
}
/// A centre and radius within those bounds: particle_values_ok may then compute.
inline bool particle_bits_ok(const double* c, double radius) {
  return magnitude_below(c[0], 1e300) && magnitude_below(c[1], 1e300) && magnitude_below(c[2], 1e300) &&
         radius_in_bounds(radius);
}

/// One comparison chain settles r <= 0 and volumes doubles cannot hold, for values that
/// pass particle_bits_ok (whose bounds it repeats: every comparison with NaN is false).
inline bool particle_values_ok(const double* c, double radius, double volume) {
  return std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2]) + radius < 1e300 && radius > 0 &&
         volume >= std::numeric_limits<double>::min() && volume < 1e300;
}

/// The box a sphere must stay within not to count as beyond the mesh: a grid's box widened
/// by outside_tolerance, infinite along periodic axes and on a polyMesh (where what lies
/// outside is the method's business).
struct SphereBounds {
  double lo[3], hi[3];
  bool beyond(const double* c, double r) const {
    return (c[0] - r < lo[0]) | (c[0] + r > hi[0]) | (c[1] - r < lo[1]) | (c[1] + r > hi[1]) | (c[2] - r < lo[2]) |
           (c[2] + r > hi[2]);
  }
};

}  // namespace vfe::detail

// The host's particle arrays as the engine reads them: pointers with byte strides (an array
// of structs is read in place, nothing is copied), and their validation.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <cstring>
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
};

}  // namespace vfe::detail

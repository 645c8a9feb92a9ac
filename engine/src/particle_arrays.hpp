// The host's particle arrays as the engine reads them: pointers with byte strides (an array
// of structs is read in place, nothing is copied), and their validation.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cfenv>
#include <cmath>
#include <cstdint>
#include <limits>

#ifdef __SSE2__
#include <xmmintrin.h>
#endif

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

/// Holds the calling thread's floating-point traps while it lives: validation computes with
/// values it has not checked yet (a NaN compared, a radius cubed), and a host that traps
/// invalid operations, division by zero or overflow (OpenFOAM does by default) must get the
/// error naming the particle, not a signal. Where traps were on it restores the thread's
/// state as it was, flags included; where none were, it costs one read of the control word.
class HeldFloatingPointTraps {
 public:
  HeldFloatingPointTraps() {
#ifdef __SSE2__
    csr_ = _mm_getcsr();
    held_ = (csr_ & _MM_MASK_MASK) != _MM_MASK_MASK;
    if (held_) _mm_setcsr(csr_ | _MM_MASK_MASK);
#else
    held_ = std::feholdexcept(&env_) == 0;
#endif
  }
  ~HeldFloatingPointTraps() {
#ifdef __SSE2__
    if (held_) _mm_setcsr(csr_);
#else
    if (held_) std::fesetenv(&env_);
#endif
  }
  HeldFloatingPointTraps(const HeldFloatingPointTraps&) = delete;
  HeldFloatingPointTraps& operator=(const HeldFloatingPointTraps&) = delete;

 private:
#ifdef __SSE2__
  unsigned csr_ = 0;
#else
  std::fenv_t env_;
#endif
  bool held_ = false;
};

/// One comparison chain settles NaN, infinities, r <= 0 and volumes doubles cannot hold
/// (every comparison with NaN is false).
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

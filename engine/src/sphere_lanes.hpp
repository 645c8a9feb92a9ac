// Four spheres as the lanes of GCC vectors: the types and the loads that the passes over
// many spheres (sphere_pass.cpp, pmm_plan.cpp) share. One source serves the baseline x86-64
// build (two SSE2 registers per vector) and the x86-64-v3 one (one AVX register), with the
// same operations on every lane either way.
#pragma once

#include "particle_arrays.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <numbers>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
/// The passes have a second build for x86-64-v3 (AVX2, FMA), chosen at run time.
#define VFE_HAS_V3_BUILD 1
namespace vfe::detail {
/// Whether this CPU runs the x86-64-v3 builds.
inline bool cpu_has_x86_64_v3() {
  static const bool yes = __builtin_cpu_supports("x86-64-v3");
  return yes;
}
}  // namespace vfe::detail
#endif

namespace vfe::detail::lanes {

using v4d = double __attribute__((vector_size(32)));
using v4l = std::int64_t __attribute__((vector_size(32)));
using v4i = std::int32_t __attribute__((vector_size(16)));
using v4f = float __attribute__((vector_size(16)));

// Lanes i, j, k, l of the eight of a and b (GCC and Clang name the builtin differently; a
// macro, since a function returning a 256-bit vector would change the baseline build's ABI).
#if defined(__clang__)
#define VFE_SHUFFLE4(a, b, i, j, k, l) __builtin_shufflevector(a, b, i, j, k, l)
#else
#define VFE_SHUFFLE4(a, b, i, j, k, l) __builtin_shuffle(a, b, ::vfe::detail::lanes::v4l{i, j, k, l})
#endif

inline double read_double(const char* p) {
  double x;
  std::memcpy(&x, p, sizeof x);
  return x;
}

/// Spheres at c and r (centres cs and radii rs bytes apart) as lanes: `lanes` of them
/// (1 to 4), the lanes beyond repeating the last. kPacked: cs = 24 and rs = 8, where four
/// whole spheres are three loads of x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3, transposed.
template <bool kPacked>
[[gnu::always_inline]] inline void load_spheres(const char* c, const char* r, std::int64_t cs, std::int64_t rs,
                                                int lanes, v4d& x, v4d& y, v4d& z, v4d& rad) {
  if (kPacked && lanes == 4) {
    v4d a0, a1, a2;
    std::memcpy(&a0, c, sizeof a0);
    std::memcpy(&a1, c + 32, sizeof a1);
    std::memcpy(&a2, c + 64, sizeof a2);
    std::memcpy(&rad, r, sizeof rad);
    const v4d p = VFE_SHUFFLE4(a0, a1, 0, 1, 6, 7);  // x0 y0 x2 y2
    const v4d q = VFE_SHUFFLE4(a0, a2, 2, 3, 4, 5);  // z0 x1 z2 x3
    const v4d s = VFE_SHUFFLE4(a1, a2, 0, 1, 6, 7);  // y1 z1 y3 z3
    x = VFE_SHUFFLE4(p, q, 0, 5, 2, 7);
    y = VFE_SHUFFLE4(p, s, 1, 4, 3, 6);
    z = VFE_SHUFFLE4(q, s, 0, 5, 2, 7);
    return;
  }
  const std::int64_t j1 = std::min(1, lanes - 1), j2 = std::min(2, lanes - 1), j3 = std::min(3, lanes - 1);
  x = v4d{read_double(c), read_double(c + j1 * cs), read_double(c + j2 * cs), read_double(c + j3 * cs)};
  y = v4d{read_double(c + 8), read_double(c + j1 * cs + 8), read_double(c + j2 * cs + 8), read_double(c + j3 * cs + 8)};
  z = v4d{read_double(c + 16), read_double(c + j1 * cs + 16), read_double(c + j2 * cs + 16),
          read_double(c + j3 * cs + 16)};
  rad = v4d{read_double(r), read_double(r + j1 * rs), read_double(r + j2 * rs), read_double(r + j3 * rs)};
}

/// How many spheres ahead the passes ask for the particle stream: this machine's hardware
/// prefetcher does not follow it, and 16 ahead (0.4 KB) was too short for direct's pass
/// (docs/performance.md, "pmm's counts by sets of split axes").
inline constexpr int kPrefetchAhead = 64;

/// Asks for the four spheres kPrefetchAhead ahead of those at c and r (past the end is harmless).
template <bool kPacked>
[[gnu::always_inline]] inline void prefetch_spheres(const char* c, const char* r, std::int64_t cs, std::int64_t rs) {
  if constexpr (kPacked) {
    __builtin_prefetch(c + kPrefetchAhead * 24);
    __builtin_prefetch(c + kPrefetchAhead * 24 + 64);
    __builtin_prefetch(r + kPrefetchAhead * 8);
  } else {
    for (int l = 0; l < 4; ++l) {
      __builtin_prefetch(c + (kPrefetchAhead + l) * cs);
      __builtin_prefetch(r + (kPrefetchAhead + l) * rs);
    }
  }
}

/// sphere_volume's factor, the same rounding: the passes' volumes k4pi3 r r r are its bits.
inline constexpr double k4pi3 = 4.0 / 3.0 * std::numbers::pi;

/// Whether pa's arrays are packed (load_spheres<true>).
inline bool packed(const ParticleArrays& pa) { return pa.centres_stride == 24 && pa.radii_stride == 8; }

}  // namespace vfe::detail::lanes

#include "sphere_pass.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <numbers>
#include <type_traits>

namespace vfe::detail {
namespace {

// GCC's vector types: one source for both builds, four particles per step as two SSE2
// registers or one AVX register, the same operations on every lane either way.
using v4d = double __attribute__((vector_size(32)));
using v4l = std::int64_t __attribute__((vector_size(32)));
using v4i = std::int32_t __attribute__((vector_size(16)));

// Lanes i, j, k, l of the eight of a and b (GCC and Clang name the builtin differently; a
// macro, since a function returning a 256-bit vector would change the baseline build's ABI).
#if defined(__clang__)
#define VFE_SHUFFLE4(a, b, i, j, k, l) __builtin_shufflevector(a, b, i, j, k, l)
#else
#define VFE_SHUFFLE4(a, b, i, j, k, l) __builtin_shuffle(a, b, v4l{i, j, k, l})
#endif

constexpr double k4pi3 = 4.0 / 3.0 * std::numbers::pi;  // sphere_volume's factor, the same rounding

inline double read_double(const char* p) {
  double x;
  std::memcpy(&x, p, sizeof x);
  return x;
}

/// The chunk again one by one, after the fast loop met a bad particle: a.first_bad, and
/// the sums over the good ones.
void recheck_spheres(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                     Validation& a) {
  for (std::int64_t p = first; p < first + count; ++p) {
    const double* c = reinterpret_cast<const double*>(pa.centres + p * pa.centres_stride);
    const double r = pa.radius(p);
    const double v = k4pi3 * r * r * r;
    if (!particle_values_ok(c, r, v)) {
      a.first_bad = std::min(a.first_bad, p);
      continue;
    }
    a.volume += v;
    a.d_min = std::min(a.d_min, 2 * r);
    a.d_max = std::max(a.d_max, 2 * r);
    a.beyond += b.beyond(c, r);
  }
}

/// The pass over one chunk. kPacked: centres 24 and radii 8 bytes apart (the offsets are
/// constants and one prefetch serves four particles). kDeposit: also add each volume into
/// g's cell. Returns how many spheres it left (in left), or -1 for a chunk holding a bad
/// one. Every value the loop reads is a local: the adds into the field could alias
/// any double behind a pointer, which would make the compiler reload it each time.
template <bool kPacked, bool kDeposit>
[[gnu::always_inline]] inline std::int64_t sphere_pass(const ParticleArrays& pa, std::int64_t first,
                                                       std::int64_t count, const SphereBounds& b, const CentreGrid* g,
                                                       Validation& a, std::int64_t* left) {
  const std::int64_t cs = kPacked ? 24 : pa.centres_stride, rs = kPacked ? 8 : pa.radii_stride;
  const char* const cc = pa.centres + first * cs;
  const char* const rr = pa.radii + first * rs;
  const double lo0 = b.lo[0], lo1 = b.lo[1], lo2 = b.lo[2], hi0 = b.hi[0], hi1 = b.hi[1], hi2 = b.hi[2];
  double o0 = 0, o1 = 0, o2 = 0, i0 = 0, i1 = 0, i2 = 0, n0 = 0, n1 = 0, n2 = 0;
  std::int32_t s0 = 0, s1 = 0;
  double* field = nullptr;
  if constexpr (kDeposit) {
    o0 = g->origin[0], o1 = g->origin[1], o2 = g->origin[2];
    i0 = g->inv_spacing[0], i1 = g->inv_spacing[1], i2 = g->inv_spacing[2];
    n0 = g->cells[0], n1 = g->cells[1], n2 = g->cells[2];
    s0 = g->strides[0], s1 = g->strides[1];
    field = g->field;
  }
  const v4l magnitude = v4l{} + std::numeric_limits<std::int64_t>::max();  // every bit but the sign

  v4l ok = v4l{} - 1;
  v4l beyond = v4l{};
  v4d r_min = v4d{} + std::numeric_limits<double>::infinity(), r_max = v4d{};
  double volume = a.volume;
  std::int64_t nleft = 0;

  // The cells and volumes of the chunk first, then the adds into the field in a loop of
  // their own: a few instructions per sphere, so the processor keeps many of the adds'
  // cache misses in flight at once.
  alignas(32) std::int32_t cells[kSphereChunk + 4];
  alignas(32) double volumes[kSphereChunk + 4];

  // Particles k .. k + lanes - 1 (lanes <= 4; whole: lanes is 4). The lanes beyond repeat
  // the last particle, which changes neither the validity nor the radii's extremes, and
  // count for nothing else.
  auto step = [&](auto whole, std::int64_t k, int lanes) __attribute__((always_inline)) {
    const char* c = cc + k * cs;
    const char* r = rr + k * rs;
    v4d x, y, z, rad;
    if constexpr (kPacked) {
      // This machine's hardware prefetcher does not follow the particle stream: ask for
      // the particles 16 ahead (past the end is harmless).
      __builtin_prefetch(c + 16 * 24);
      __builtin_prefetch(c + 16 * 24 + 64);
      __builtin_prefetch(r + 16 * 8);
    } else {
      for (int l = 0; l < 4; ++l) {
        __builtin_prefetch(c + (16 + l) * cs);
        __builtin_prefetch(r + (16 + l) * rs);
      }
    }
    if constexpr (kPacked && decltype(whole)::value) {
      // Four whole particles: three loads of x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3, transposed.
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
    } else {
      const std::int64_t j1 = std::min(1, lanes - 1), j2 = std::min(2, lanes - 1), j3 = std::min(3, lanes - 1);
      x = v4d{read_double(c), read_double(c + j1 * cs), read_double(c + j2 * cs), read_double(c + j3 * cs)};
      y = v4d{read_double(c + 8), read_double(c + j1 * cs + 8), read_double(c + j2 * cs + 8),
              read_double(c + j3 * cs + 8)};
      z = v4d{read_double(c + 16), read_double(c + j1 * cs + 16), read_double(c + j2 * cs + 16),
              read_double(c + j3 * cs + 16)};
      rad = v4d{read_double(r), read_double(r + j1 * rs), read_double(r + j2 * rs), read_double(r + j3 * rs)};
    }
    const v4l valid = {-1, lanes > 1 ? -1 : 0, lanes > 2 ? -1 : 0, lanes > 3 ? -1 : 0};
    const v4d v = k4pi3 * rad * rad * rad;
    // particle_values_ok on four lanes (r > 0 follows from v >= the smallest normal).
    const v4d ax = (v4d)((v4l)x & magnitude), ay = (v4d)((v4l)y & magnitude), az = (v4d)((v4l)z & magnitude);
    ok &= (ax + ay + az + rad < 1e300) & (v >= std::numeric_limits<double>::min()) & (v < 1e300);
    r_min = rad < r_min ? rad : r_min;
    r_max = rad > r_max ? rad : r_max;
    beyond -= valid & ((x - rad < lo0) | (x + rad > hi0) | (y - rad < lo1) | (y + rad > hi1) | (z - rad < lo2) |
                       (z + rad > hi2));
    for (int l = 0; l < lanes; ++l) volume += v[l];  // in particle order, as validate sums
    if constexpr (kDeposit) {
      const v4d t0 = (x - o0) * i0, t1 = (y - o1) * i1, t2 = (z - o2) * i2;
      const v4l in = valid & (t0 >= 0) & (t0 < n0) & (t1 >= 0) & (t1 < n1) & (t2 >= 0) & (t2 < n2);
      // On [0, n) floor is truncation. A lane outside converts (-1, 0, 0): cell -1.
      const v4i cell = __builtin_convertvector(in ? t0 : v4d{} - 1, v4i) +
                       s0 * __builtin_convertvector(in ? t1 : v4d{}, v4i) +
                       s1 * __builtin_convertvector(in ? t2 : v4d{}, v4i);
      std::memcpy(cells + k, &cell, sizeof cell);
      std::memcpy(volumes + k, &v, sizeof v);
    }
  };
  std::int64_t k = 0;
  for (; k + 4 <= count; k += 4) step(std::true_type{}, k, 4);
  if (k < count) step(std::false_type{}, k, static_cast<int>(count - k));
  if constexpr (kDeposit)
    for (std::int64_t i = 0; i < count; ++i) {
      if (cells[i] >= 0) [[likely]]
        field[cells[i]] += volumes[i];
      else
        left[nleft++] = first + i;
    }

  if ((ok[0] & ok[1] & ok[2] & ok[3]) == 0) [[unlikely]] {
    recheck_spheres(pa, first, count, b, a);
    return -1;
  }
  a.volume = volume;
  a.d_min = std::min(a.d_min, 2 * std::min(std::min(r_min[0], r_min[1]), std::min(r_min[2], r_min[3])));
  a.d_max = std::max(a.d_max, 2 * std::max(std::max(r_max[0], r_max[1]), std::max(r_max[2], r_max[3])));
  a.beyond += beyond[0] + beyond[1] + beyond[2] + beyond[3];
  return nleft;
}

bool packed(const ParticleArrays& pa) { return pa.centres_stride == 24 && pa.radii_stride == 8; }

template <bool kDeposit>
[[gnu::always_inline]] inline std::int64_t either_pass(const ParticleArrays& pa, std::int64_t first, std::int64_t count,
                                                       const SphereBounds& b, const CentreGrid* g, Validation& a,
                                                       std::int64_t* left) {
  return packed(pa) ? sphere_pass<true, kDeposit>(pa, first, count, b, g, a, left)
                    : sphere_pass<false, kDeposit>(pa, first, count, b, g, a, left);
}

std::int64_t baseline_pass(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                           const CentreGrid* g, Validation& a, std::int64_t* left) {
  return g ? either_pass<true>(pa, first, count, b, g, a, left) : either_pass<false>(pa, first, count, b, g, a, left);
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VFE_SPHERE_PASS_V3 1
// The same source built for AVX2 + FMA: four lanes in one register.
__attribute__((target("arch=x86-64-v3"))) std::int64_t v3_pass(const ParticleArrays& pa, std::int64_t first,
                                                                std::int64_t count, const SphereBounds& b,
                                                                const CentreGrid* g, Validation& a, std::int64_t* left) {
  return g ? either_pass<true>(pa, first, count, b, g, a, left) : either_pass<false>(pa, first, count, b, g, a, left);
}
bool has_v3() {
  static const bool yes = __builtin_cpu_supports("x86-64-v3");
  return yes;
}
#endif

std::int64_t pass(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                  const CentreGrid* g, Validation& a, std::int64_t* left, [[maybe_unused]] PassBuild build) {
#ifdef VFE_SPHERE_PASS_V3
  if (build == PassBuild::fastest && has_v3()) return v3_pass(pa, first, count, b, g, a, left);
#endif
  return baseline_pass(pa, first, count, b, g, a, left);
}

}  // namespace

bool check_sphere_chunk(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                        Validation& a, PassBuild build) {
  return pass(pa, first, count, b, nullptr, a, nullptr, build) >= 0;
}

std::int64_t deposit_sphere_chunk(const ParticleArrays& pa, std::int64_t first, std::int64_t count,
                                  const SphereBounds& b, const CentreGrid& g, Validation& a, std::int64_t* left,
                                  PassBuild build) {
  return std::max<std::int64_t>(pass(pa, first, count, b, &g, a, left, build), 0);
}

}  // namespace vfe::detail

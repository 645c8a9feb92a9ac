#include "sphere_pass.hpp"

#include "cell_bins.hpp"
#include "sphere_lanes.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <type_traits>

namespace vfe::detail {
namespace {

using namespace lanes;

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
    prefetch_spheres<kPacked>(c, r, cs, rs);
    load_spheres<kPacked && decltype(whole)::value>(c, r, cs, rs, lanes, x, y, z, rad);
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
  if constexpr (kDeposit) {
    // One loop per numbering and destination, so the grid's own field keeps its plain
    // indexed add.
    auto deposit = [&](auto&& add) __attribute__((always_inline)) {
      for (std::int64_t i = 0; i < count; ++i) {
        if (cells[i] >= 0) [[likely]]
          add(cells[i], volumes[i]);
        else
          left[nleft++] = first + i;
      }
    };
    const std::int64_t* const map = g->cell_map;
    if (g->bins) {
      BinWriter bins = *g->bins;  // a local copy: the pages' stores cannot alias its pointers
      if (map)
        deposit([&](std::int32_t c, double v) { bins.add(static_cast<std::int32_t>(map[c]), v); });
      else
        deposit([&](std::int32_t c, double v) { bins.add(c, v); });
    } else if (map) {
      deposit([&](std::int32_t c, double v) { field[map[c]] += v; });
    } else {
      deposit([&](std::int32_t c, double v) { field[c] += v; });
    }
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

#ifdef VFE_HAS_V3_BUILD
// The same source built for AVX2 + FMA: four lanes in one register.
__attribute__((target("arch=x86-64-v3"))) std::int64_t v3_pass(const ParticleArrays& pa, std::int64_t first,
                                                                std::int64_t count, const SphereBounds& b,
                                                                const CentreGrid* g, Validation& a, std::int64_t* left) {
  return g ? either_pass<true>(pa, first, count, b, g, a, left) : either_pass<false>(pa, first, count, b, g, a, left);
}
#endif

std::int64_t pass(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                  const CentreGrid* g, Validation& a, std::int64_t* left, [[maybe_unused]] PassBuild build) {
  const HeldFloatingPointTraps held;  // the values are not checked yet
#ifdef VFE_HAS_V3_BUILD
  if (build == PassBuild::fastest && cpu_has_x86_64_v3()) return v3_pass(pa, first, count, b, g, a, left);
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

#include <vfe/kernels/octant_split.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#define VFE_OCTANT_AVX2 1
#endif

namespace vfe::kernels {

void prepare_octant_split(ParticleTemplate& t) {
  t.split_points.clear();
  t.split_words = 0;
  const std::size_t n = t.size();
  if (n == 0 || n > kMaxSplitWords * 64) return;
  for (const double f : t.fractions)
    if (f != t.fractions[0]) return;
  const std::size_t words = (n + 63) / 64, stride = words * 64;
  // Padding is the origin, masked out by the counters (not NaN: converting or comparing NaN
  // raises the invalid-operation exception, which hosts such as OpenFOAM trap). The scale
  // is a power of two, so it changes no rounding.
  t.split_points.assign(3 * stride, 0.0f);
  for (std::size_t s = 0; s < n; ++s)
    for (int d = 0; d < 3; ++d) t.split_points[d * stride + s] = static_cast<float>(kSplitScale * t.points[s][d]);
  t.split_words = words;
}

namespace {

/// Per split axis, the bit masks "above the plane" over the template's words, and one
/// mask of the points too near a plane; masks hold split_words words.
struct SplitMasks {
  std::uint64_t above[3][kMaxSplitWords];
  std::uint64_t near = 0;  ///< or of all words: any point too near a plane
};

/// The points of word w that the template holds (the rest is padding).
std::uint64_t valid_bits(const ParticleTemplate& t, std::size_t w) {
  const std::size_t n = t.size();
  return w + 1 == t.split_words && n % 64 ? (std::uint64_t(1) << (n % 64)) - 1 : ~std::uint64_t(0);
}

/// counts[] from the masks (split axes in increasing order in m.above).
void counts_from_masks(const ParticleTemplate& t, const SplitMasks& m, unsigned split, std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  for (std::size_t w = 0; w < t.split_words; ++w) {
    const std::uint64_t valid = valid_bits(t, w);
    // side[d][b]: the points of this word on side b of axis d (all below for an axis not split).
    std::uint64_t side[3][2];
    int a = 0;
    for (int d = 0; d < 3; ++d) {
      const std::uint64_t above = (split >> d) & 1u ? m.above[a++][w] & valid : 0;
      side[d][0] = valid & ~above;
      side[d][1] = above;
    }
    for (int o = 0; o < 8; ++o)
      counts[o] += std::popcount(side[0][o & 1] & side[1][(o >> 1) & 1] & side[2][(o >> 2) & 1]);
  }
}

/// The straightforward float comparisons, point by point: the path of CPUs without AVX2
/// and the check of the vector path.
bool count_portable(const ParticleTemplate& t, const float* rows, const float tau[3], unsigned split,
                    std::int32_t counts[8]) {
  const std::size_t words = t.split_words, stride = words * 64;
  const float* x = t.split_points.data();
  const float* y = x + stride;
  const float* z = y + stride;
  const float scale = static_cast<float>(kSplitScale), guard = 0.5f;  // the points are scaled
  SplitMasks m;
  int a = 0;
  for (int d = 0; d < 3; ++d) {
    if (!((split >> d) & 1u)) continue;
    const float* r = rows + 3 * d;
    for (std::size_t w = 0; w < words; ++w) {
      std::uint64_t above = 0, near = 0;
      for (int b = 0; b < 64; ++b) {
        const std::size_t s = w * 64 + b;
        const float dot = r[0] * x[s] + r[1] * y[s] + r[2] * z[s];
        above |= std::uint64_t(dot >= scale * tau[d]) << b;
        near |= std::uint64_t(std::fabs(dot - scale * tau[d]) < guard) << b;
      }
      m.above[a][w] = above;
      m.near |= near & valid_bits(t, w);
    }
    ++a;
  }
  if (m.near) return false;
  counts_from_masks(t, m, split, counts);
  return true;
}

template <unsigned kSplit>
bool count_portable_split(const ParticleTemplate& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  return count_portable(t, rows, tau, kSplit, counts);
}

/// No split axis: one octant holds every point.
bool count_unsplit(const ParticleTemplate& t, const float*, const float*, std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  counts[0] = static_cast<std::int32_t>(t.size());
  return true;
}

/// A batch by calls of one particle's code (inlined where it is visible).
template <auto kCount>
void count_batch(const ParticleTemplate& t, const OctantQuery* queries, std::size_t n, std::int32_t* counts,
                 std::uint8_t* decided) {
  for (std::size_t k = 0; k < n; ++k) decided[k] = kCount(t, queries[k].rows, queries[k].tau, counts + 8 * k);
}

/// Octant counts from P[S], the points above every plane of axis set S (P[0] = all
/// points, P[S] = 0 for a set with an axis not split): per split axis d, taking the points
/// above d out of each set without d leaves, after every split axis, the points above
/// exactly the planes of each set (inclusion and exclusion). Compile-time sets: it unrolls
/// into a few subtractions.
template <unsigned kSplit>
[[gnu::always_inline]] inline void counts_from_above(std::int32_t P[8], std::int32_t counts[8]) {
#pragma GCC unroll 3
  for (unsigned d = 0; d < 3; ++d) {
    if (!((kSplit >> d) & 1u)) continue;
#pragma GCC unroll 8
    for (unsigned S = 0; S < 8; ++S)
      if ((S >> d) & 1u && (S & ~kSplit) == 0) P[S ^ (1u << d)] -= P[S];
  }
#pragma GCC unroll 8
  for (unsigned o = 0; o < 8; ++o) counts[o] = P[o];
}

#ifdef VFE_OCTANT_AVX2
/// Per split axis d the scaled distance k = round(kSplitScale (R_d . q - tau_d)) of each
/// point as an integer (the points are stored scaled): k = 0 is a point within the guard
/// band (the particle goes to double), k > 0 above, k < 0 below (the padding of the last
/// group gets its sign bit set: below, never in the band). Four groups of eight points
/// pack with saturation (which keeps sign and zero) into 32 bytes, whose sign bits are one
/// movemask: 32 points per axis in a few instructions. The packs interleave the points in a
/// fixed order, the same for every axis, and a count of "above on every axis of a set" does
/// not depend on the order.
/// kGroups: the template's groups of eight points when it has at most 64 (the loops then
/// unroll into straight code), 0 for any size.
template <unsigned kSplit, std::size_t kGroups>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_avx2_body(
    const ParticleTemplate& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  constexpr int kAxes = std::popcount(kSplit);
  constexpr unsigned kRest = kSplit & (kSplit - 1);  // the split axes after the first
  constexpr int axis[3] = {std::countr_zero(kSplit), std::countr_zero(kRest), std::countr_zero(kRest & (kRest - 1))};
  __m256 r0[kAxes], r1[kAxes], r2[kAxes], shift[kAxes];
#pragma GCC unroll 3
  for (int a = 0; a < kAxes; ++a) {
    const float* r = rows + 3 * axis[a];
    r0[a] = _mm256_set1_ps(r[0]), r1[a] = _mm256_set1_ps(r[1]), r2[a] = _mm256_set1_ps(r[2]);
    shift[a] = _mm256_set1_ps(tau[axis[a]] * -static_cast<float>(kSplitScale));
  }
  const std::size_t n = t.size(), stride = kGroups ? 64 : t.split_words * 64;
  const std::size_t groups = kGroups ? kGroups : (n + 7) / 8, end = kGroups ? 64 : n;
  const float* x = t.split_points.data();
  const float* y = x + stride;
  const float* z = y + stride;
  const __m256i below_all = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::min());
  const int last_points = static_cast<int>(n - 8 * (groups - 1));  // 1 to 8
  const __m256i last_padding = _mm256_and_si256(
      below_all, _mm256_cmpgt_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(last_points - 1)));
  __m256i near = _mm256_setzero_si256();
  std::int32_t P[8] = {};
  P[0] = static_cast<std::int32_t>(n);
  for (std::size_t first = 0; first < end; first += 64) {
    std::uint64_t above[kAxes] = {};
#pragma GCC unroll 2
    for (std::size_t half = 0; half < 2; ++half) {
      const std::size_t group = first / 8 + 4 * half;  // the half's first group
      if (group >= groups) break;
      // Axis by axis (the points are memory operands of the FMAs, reloaded from L1), so
      // three split axes fit the sixteen vector registers.
#pragma GCC unroll 3
      for (int a = 0; a < kAxes; ++a) {
        __m256i k[4];
#pragma GCC unroll 4
        for (std::size_t g = 0; g < 4; ++g) {
          const std::size_t s = 8 * (group + g);
          k[g] = group + g < groups
                     ? _mm256_cvtps_epi32(_mm256_fmadd_ps(
                           r2[a], _mm256_loadu_ps(z + s),
                           _mm256_fmadd_ps(r1[a], _mm256_loadu_ps(y + s),
                                           _mm256_fmadd_ps(r0[a], _mm256_loadu_ps(x + s), shift[a]))))
                     : below_all;  // beyond the template: below every plane, no work
          if (group + g + 1 == groups) k[g] = _mm256_or_si256(k[g], last_padding);
        }
        const __m256i bytes = _mm256_packs_epi16(_mm256_packs_epi32(k[0], k[1]), _mm256_packs_epi32(k[2], k[3]));
        near = _mm256_or_si256(near, _mm256_cmpeq_epi8(bytes, _mm256_setzero_si256()));
        above[a] |= std::uint64_t(~static_cast<std::uint32_t>(_mm256_movemask_epi8(bytes))) << (32 * half);
      }
    }
#pragma GCC unroll 8
    for (unsigned S = 1; S < 8; ++S) {
      if (S & ~kSplit) continue;
      std::uint64_t all = ~std::uint64_t(0);
#pragma GCC unroll 3
      for (int a = 0; a < kAxes; ++a)
        if ((S >> axis[a]) & 1u) all &= above[a];
      P[S] += static_cast<std::int32_t>(_mm_popcnt_u64(all));
    }
  }
  if (!_mm256_testz_si256(near, near)) return false;
  counts_from_above<kSplit>(P, counts);
  return true;
}

template <unsigned kSplit, std::size_t kGroups>
__attribute__((target("avx2,fma,popcnt"))) bool count_avx2(const ParticleTemplate& t, const float* rows,
                                                         const float tau[3], std::int32_t counts[8]) {
  return count_avx2_body<kSplit, kGroups>(t, rows, tau, counts);
}

template <unsigned kSplit, std::size_t kGroups>
__attribute__((target("avx2,fma,popcnt"))) void count_batch_avx2(const ParticleTemplate& t,
                                                               const OctantQuery* queries, std::size_t n,
                                                               std::int32_t* counts, std::uint8_t* decided) {
  for (std::size_t k = 0; k < n; ++k)
    decided[k] = count_avx2_body<kSplit, kGroups>(t, queries[k].rows, queries[k].tau, counts + 8 * k);
}

template <std::size_t kGroups>
constexpr OctantCounter vector_counter() {
  return {{count_unsplit, count_avx2<1, kGroups>, count_avx2<2, kGroups>, count_avx2<3, kGroups>,
           count_avx2<4, kGroups>, count_avx2<5, kGroups>, count_avx2<6, kGroups>, count_avx2<7, kGroups>},
          {count_batch<count_unsplit>, count_batch_avx2<1, kGroups>, count_batch_avx2<2, kGroups>,
           count_batch_avx2<3, kGroups>, count_batch_avx2<4, kGroups>, count_batch_avx2<5, kGroups>,
           count_batch_avx2<6, kGroups>, count_batch_avx2<7, kGroups>}};
}

bool has_avx2() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }
#endif

}  // namespace

const OctantCounter& octant_counter(const ParticleTemplate& t, SplitPath path) {
  static const OctantCounter portable{
      {count_unsplit, count_portable_split<1>, count_portable_split<2>, count_portable_split<3>,
       count_portable_split<4>, count_portable_split<5>, count_portable_split<6>, count_portable_split<7>},
      {count_batch<count_unsplit>, count_batch<count_portable_split<1>>, count_batch<count_portable_split<2>>,
       count_batch<count_portable_split<3>>, count_batch<count_portable_split<4>>,
       count_batch<count_portable_split<5>>, count_batch<count_portable_split<6>>,
       count_batch<count_portable_split<7>>}};
#ifdef VFE_OCTANT_AVX2
  // Entry g: templates of g groups of eight points (at most 64 points); entry 0: any size.
  static const OctantCounter vector[9] = {vector_counter<0>(), vector_counter<1>(), vector_counter<2>(),
                                          vector_counter<3>(), vector_counter<4>(), vector_counter<5>(),
                                          vector_counter<6>(), vector_counter<7>(), vector_counter<8>()};
  static const bool avx2 = has_avx2();
  if (path == SplitPath::fastest && avx2) return vector[t.split_words == 1 ? (t.size() + 7) / 8 : 0];
#endif
  (void)t, (void)path;
  return portable;
}

bool count_octants(const ParticleTemplate& t, const Eigen::Matrix3d& R, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  float rows[9];
  rotation_rows(R, rows);
  return count_octants(t, rows, split, tau, counts, path);
}

bool count_octants(const ParticleTemplate& t, const float* rows, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  const float taus[3] = {static_cast<float>(tau[0]), static_cast<float>(tau[1]), static_cast<float>(tau[2])};
  return octant_counter(t, path).by_split[split & 7u](t, rows, taus, counts);
}

}  // namespace vfe::kernels

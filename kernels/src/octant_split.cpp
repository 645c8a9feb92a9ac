#include <vfe/kernels/octant_split.hpp>

#include <algorithm>
#include <cmath>

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
  t.split_points.assign(3 * stride, 0.0f);
  for (std::size_t s = 0; s < n; ++s)
    for (int d = 0; d < 3; ++d) t.split_points[d * stride + s] = static_cast<float>(t.points[s][d]);
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

/// counts[] from the masks (split axes in increasing order in m.above); inlined into each
/// caller so popcount compiles to the instruction where the caller's target has it.
[[gnu::always_inline]] inline void counts_from_masks(const ParticleTemplate& t, const SplitMasks& m, unsigned split,
                                                     std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  for (std::size_t w = 0; w < t.split_words; ++w) {
    const std::uint64_t valid = valid_bits(t, w);
    // side[d][b]: the points of this word on side b of axis d (all below for an axis not
    // split). Branch-free: eight popcounts per word whatever the split.
    std::uint64_t side[3][2];
    int a = 0;
    for (int d = 0; d < 3; ++d) {
      const std::uint64_t above = (split >> d) & 1u ? m.above[a++][w] & valid : 0;
      side[d][0] = valid & ~above;
      side[d][1] = above;
    }
    for (int o = 0; o < 8; ++o)
      counts[o] += __builtin_popcountll(side[0][o & 1] & side[1][(o >> 1) & 1] & side[2][(o >> 2) & 1]);
  }
}

void masks_portable(const ParticleTemplate& t, const float* rows, const int axes[3], int naxes,
                    const float tau[3], float guard, SplitMasks& m) {
  const std::size_t words = t.split_words, stride = words * 64;
  const float* x = t.split_points.data();
  const float* y = x + stride;
  const float* z = y + stride;
  for (int a = 0; a < naxes; ++a) {
    const float* r = rows + 3 * axes[a];
    for (std::size_t w = 0; w < words; ++w) {
      std::uint64_t above = 0, near = 0;
      for (int b = 0; b < 64; ++b) {
        const std::size_t s = w * 64 + b;
        const float dot = r[0] * x[s] + r[1] * y[s] + r[2] * z[s];
        above |= std::uint64_t(dot >= tau[a]) << b;
        near |= std::uint64_t(std::fabs(dot - tau[a]) < guard) << b;
      }
      m.above[a][w] = above;
      m.near |= near & valid_bits(t, w);
    }
  }
}

#ifdef VFE_OCTANT_AVX2
/// The masks of kAxes split axes (a compile-time count, so the rows stay in registers).
template <int kAxes>
__attribute__((target("avx2,fma,popcnt"))) bool count_avx2_axes(const ParticleTemplate& t, const float* rows,
                                                               const int axes[3], const float tau[3], unsigned split,
                                                               std::int32_t counts[8]) {
  SplitMasks m;
  const std::size_t words = t.split_words, stride = words * 64;
  const float* x = t.split_points.data();
  const float* y = x + stride;
  const float* z = y + stride;
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const std::size_t n = t.size();
  __m256 r0[kAxes], r1[kAxes], r2[kAxes], th[kAxes];
  for (int a = 0; a < kAxes; ++a) {
    const float* r = rows + 3 * axes[a];
    r0[a] = _mm256_set1_ps(r[0]), r1[a] = _mm256_set1_ps(r[1]), r2[a] = _mm256_set1_ps(r[2]);
    th[a] = _mm256_set1_ps(tau[a]);
  }
  // The smallest |R_d . q - tau_d| seen; padding points (zeros) take part, which at worst
  // sends a particle with tau_d near 0 to the double path.
  __m256 nearest = _mm256_set1_ps(1.0f);
  for (std::size_t w = 0; w < words; ++w) {
    std::uint64_t above[kAxes] = {};
    const std::size_t groups = std::min<std::size_t>(8, (n - 64 * w + 7) / 8);  // padding beyond: zeros
    for (std::size_t k = 0; k < groups; ++k) {
      const std::size_t s = w * 64 + 8 * k;
      const __m256 px = _mm256_loadu_ps(x + s), py = _mm256_loadu_ps(y + s), pz = _mm256_loadu_ps(z + s);
      for (int a = 0; a < kAxes; ++a) {
        const __m256 dot = _mm256_fmadd_ps(r2[a], pz, _mm256_fmadd_ps(r1[a], py, _mm256_mul_ps(r0[a], px)));
        nearest = _mm256_min_ps(nearest, _mm256_and_ps(_mm256_sub_ps(dot, th[a]), abs_mask));
        above[a] |= std::uint64_t(unsigned(_mm256_movemask_ps(_mm256_cmp_ps(dot, th[a], _CMP_GE_OQ)))) << (8 * k);
      }
    }
    for (int a = 0; a < kAxes; ++a) m.above[a][w] = above[a];
  }
  const __m128 low = _mm_min_ps(_mm256_castps256_ps128(nearest), _mm256_extractf128_ps(nearest, 1));
  const __m128 pair = _mm_min_ps(low, _mm_movehl_ps(low, low));
  if (_mm_cvtss_f32(_mm_min_ss(pair, _mm_shuffle_ps(pair, pair, 1))) < static_cast<float>(kSplitGuard)) return false;
  counts_from_masks(t, m, split, counts);
  return true;
}

bool count_avx2(const ParticleTemplate& t, const float* rows, const int axes[3], int naxes, const float tau[3],
                unsigned split, std::int32_t counts[8]) {
  switch (naxes) {
    case 1: return count_avx2_axes<1>(t, rows, axes, tau, split, counts);
    case 2: return count_avx2_axes<2>(t, rows, axes, tau, split, counts);
    default: return count_avx2_axes<3>(t, rows, axes, tau, split, counts);
  }
}

bool has_avx2() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}
#endif

}  // namespace

bool count_octants(const ParticleTemplate& t, const Eigen::Matrix3d& R, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  float rows[9];
  rotation_rows(R, rows);
  return count_octants(t, rows, split, tau, counts, path);
}

bool count_octants(const ParticleTemplate& t, const float* rows, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  int axes[3], naxes = 0;
  float taus[3];
  for (int d = 0; d < 3; ++d)
    if ((split >> d) & 1u) {
      axes[naxes] = d;
      taus[naxes++] = static_cast<float>(tau[d]);
    }
  if (naxes == 0) {  // one octant holds every point
    for (int o = 0; o < 8; ++o) counts[o] = 0;
    counts[0] = static_cast<std::int32_t>(t.size());
    return true;
  }
#ifdef VFE_OCTANT_AVX2
  if (path == SplitPath::fastest && has_avx2()) return count_avx2(t, rows, axes, naxes, taus, split, counts);
#endif
  SplitMasks m;
  masks_portable(t, rows, axes, naxes, taus, static_cast<float>(kSplitGuard), m);
  if (m.near) return false;
  counts_from_masks(t, m, split, counts);
  return true;
}

}  // namespace vfe::kernels

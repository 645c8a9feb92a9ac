#include "pmm_plan.hpp"

#include "sphere_lanes.hpp"

#include <vfe/kernels/particle_template.hpp>

#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#endif

namespace vfe::detail {
namespace {

using namespace lanes;

using v4u = std::uint64_t __attribute__((vector_size(32)));

/// The rotation keys of spheres p to p + lanes - 1 (pa.rotation_key), the lanes beyond
/// repeating the last.
[[gnu::always_inline]] inline void rotation_keys(const ParticleArrays& pa, std::int64_t p, int lanes, v4u& keys) {
  const std::int64_t j1 = std::min(1, lanes - 1), j2 = std::min(2, lanes - 1), j3 = std::min(3, lanes - 1);
  if (!pa.ids)
    keys = v4u{} + std::uint64_t(p) + v4u{0, std::uint64_t(j1), std::uint64_t(j2), std::uint64_t(j3)};
  else
    keys = v4u{pa.rotation_key(p), pa.rotation_key(p + j1), pa.rotation_key(p + j2), pa.rotation_key(p + j3)};
}

/// Four spheres (lanes past `lanes` repeat the last) per step, from entry k of out. Per axis
/// the operations of PmmQuick in the same order: a = (c - half - o) / h and
/// b = (c + half - o) / h as products with 1 / h, their truncations (a >= 0 is checked
/// first), and tau = (1 - ((c - o) / h - lo)) h / r rounded to float.
template <bool kPacked>
[[gnu::always_inline]] inline void plan_four(const ParticleArrays& pa, std::int64_t p, int lanes, const QuickGrid& g,
                                             QuickWindows& out, std::int64_t k) {
  const std::int64_t cs = kPacked ? 24 : pa.centres_stride, rs = kPacked ? 8 : pa.radii_stride;
  const char* c = pa.centres + p * cs;
  const char* rp = pa.radii + p * rs;
  prefetch_spheres<kPacked>(c, rp, cs, rs);
  v4d x0, x1, x2, r;
  load_spheres<kPacked>(c, rp, cs, rs, lanes, x0, x1, x2, r);
  const v4d xyz[3] = {x0, x1, x2};
  const v4d half = r * g.reach;
  // Spheres too small to count get no thresholds (h / r could pass float's range).
  const v4l countable_r = (v4l)(r > g.min_radius);
  const v4d inv_r = (v4d)((v4l)(1.0 / r) & countable_r);
  v4l inside = v4l{} - 1;
  v4i extra = v4i{}, two = v4i{}, cell = v4i{};
  v4f tau[3];
  const std::int32_t stride[3] = {1, g.nx, g.nxy};
  for (int d = 0; d < 3; ++d) {
    const v4d x = xyz[d];
    const v4d a = (x - half - g.origin[d]) * g.inv_h[d], b = (x + half - g.origin[d]) * g.inv_h[d];
    inside &= (v4l)(a >= 0.0) & (v4l)(b < g.hi_bound[d]);
    // Outside lanes convert zeros: their results are not read.
    const v4d as = (v4d)((v4l)a & inside), bs = (v4d)((v4l)b & inside);
    const v4i i = __builtin_convertvector(as, v4i), j = __builtin_convertvector(bs, v4i);
    extra |= j - i;
    two |= (j - i) << d;
    cell += i * stride[d];
    const v4d base = (x - g.origin[d]) * g.inv_h[d] - __builtin_convertvector(i, v4d);
    tau[d] = __builtin_convertvector((1.0 - base) * g.h[d] * inv_r, v4f);
  }
  const v4i in = __builtin_convertvector(inside, v4i), large = __builtin_convertvector(countable_r, v4i);
  const v4i countable = large & (extra == 1) & (g.countable ? v4i{} - 1 : v4i{});
  const v4i counted = in & countable, fast = in & (extra == 0);
  const v4i path = (two & counted) | (~(counted | fast) & std::int32_t{QuickWindows::general});
  const v4d volume = k4pi3 * r * r * r;
  v4u keys;
  rotation_keys(pa, p, lanes, keys);
  kernels::rotation_bank_slots(keys, g.seed);
  const v4i slot = __builtin_convertvector(keys, v4i);
  std::memcpy(out.path + k, &path, sizeof path);
  std::memcpy(out.cell + k, &cell, sizeof cell);
  std::memcpy(out.slot + k, &slot, sizeof slot);
  for (int d = 0; d < 3; ++d) std::memcpy(out.tau[d] + k, &tau[d], sizeof tau[d]);
  std::memcpy(out.volume + k, &volume, sizeof volume);
}

/// Spheres [first, first + count) into out.
template <bool kPacked>
[[gnu::always_inline]] inline void plan_block(const ParticleArrays& pa, std::int64_t first, std::int64_t count,
                                              const QuickGrid& g, QuickWindows& out) {
  std::int64_t k = 0;
  for (; k + 4 <= count; k += 4) plan_four<kPacked>(pa, first + k, 4, g, out, k);
  if (k < count) plan_four<kPacked>(pa, first + k, static_cast<int>(count - k), g, out, k);
}

void plan_all(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const QuickGrid& g,
              QuickWindows& out) {
  packed(pa) ? plan_block<true>(pa, first, count, g, out) : plan_block<false>(pa, first, count, g, out);
}

#ifdef VFE_HAS_V3_BUILD
__attribute__((target("arch=x86-64-v3"))) void plan_all_v3(const ParticleArrays& pa, std::int64_t first,
                                                            std::int64_t count, const QuickGrid& g, QuickWindows& out) {
  packed(pa) ? plan_block<true>(pa, first, count, g, out) : plan_block<false>(pa, first, count, g, out);
}
/// plan_four for eight packed spheres at once in AVX-512 registers (GCC's generic vectors of
/// eight lanes turn into scalar code): the same operations in the same order per lane, so
/// the same bits.
[[gnu::always_inline]] inline __attribute__((target("arch=x86-64-v4"))) void plan_eight_packed(
    const ParticleArrays& pa, std::int64_t p, const QuickGrid& g, QuickWindows& out, std::int64_t k) {
  const char* cb = pa.centres + p * 24;
  const char* rb = pa.radii + p * 8;
  prefetch_spheres<true>(cb, rb, 24, 8);
  prefetch_spheres<true>(cb + 4 * 24, rb + 4 * 8, 24, 8);
  const double* c = reinterpret_cast<const double*>(cb);
  // x0 y0 z0 x1 ... z7 in three registers, transposed by two permutes per coordinate: lane l
  // of coordinate d is element 3 l + d, from a0 and a1 below 16, else from a2.
  const __m512d a0 = _mm512_loadu_pd(c), a1 = _mm512_loadu_pd(c + 8), a2 = _mm512_loadu_pd(c + 16);
  __m512d xyz[3];
  for (int d = 0; d < 3; ++d) {
    // Lanes 0 to 4 (and 5 for d = 0, element 15) from a0 and a1; the second permute fills the rest.
    const __m512i first = _mm512_setr_epi64(d, d + 3, d + 6, d + 9, d + 12, d == 0 ? 15 : 0, 0, 0);
    const __m512d t = _mm512_permutex2var_pd(a0, first, a1);
    // Lanes from a2 (its index 8 + element - 16): elements 18 and 21 for d = 0, else d + 15,
    // d + 18 and d + 21.
    const __m512i second = d == 0 ? _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 8 + 2, 8 + 5)
                                  : _mm512_setr_epi64(0, 1, 2, 3, 4, 8 + (d - 1), 8 + (d + 2), 8 + (d + 5));
    xyz[d] = _mm512_permutex2var_pd(t, second, a2);
  }
  const __m512d r = _mm512_loadu_pd(reinterpret_cast<const double*>(rb));
  const __m512d half = _mm512_mul_pd(r, _mm512_set1_pd(g.reach));
  const __mmask8 countable_r = _mm512_cmp_pd_mask(r, _mm512_set1_pd(g.min_radius), _CMP_GT_OQ);
  const __m512d inv_r = _mm512_maskz_mov_pd(countable_r, _mm512_div_pd(_mm512_set1_pd(1.0), r));
  __mmask8 inside = 0xFF;
  __m256i extra = _mm256_setzero_si256(), two = _mm256_setzero_si256(), cell = _mm256_setzero_si256();
  __m256 tau[3];
  const std::int32_t stride[3] = {1, g.nx, g.nxy};
  for (int d = 0; d < 3; ++d) {
    const __m512d x = xyz[d], origin = _mm512_set1_pd(g.origin[d]), inv_h = _mm512_set1_pd(g.inv_h[d]);
    const __m512d a = _mm512_mul_pd(_mm512_sub_pd(_mm512_sub_pd(x, half), origin), inv_h);
    const __m512d b = _mm512_mul_pd(_mm512_sub_pd(_mm512_add_pd(x, half), origin), inv_h);
    inside &= _mm512_cmp_pd_mask(a, _mm512_setzero_pd(), _CMP_GE_OQ) &
              _mm512_cmp_pd_mask(b, _mm512_set1_pd(g.hi_bound[d]), _CMP_LT_OQ);
    // Outside lanes convert zeros: their results are not read.
    const __m256i i = _mm512_cvttpd_epi32(_mm512_maskz_mov_pd(inside, a));
    const __m256i j = _mm512_cvttpd_epi32(_mm512_maskz_mov_pd(inside, b));
    const __m256i width = _mm256_sub_epi32(j, i);
    extra = _mm256_or_si256(extra, width);
    two = _mm256_or_si256(two, _mm256_slli_epi32(width, d));
    cell = _mm256_add_epi32(cell, _mm256_mullo_epi32(i, _mm256_set1_epi32(stride[d])));
    const __m512d base = _mm512_sub_pd(_mm512_mul_pd(_mm512_sub_pd(x, origin), inv_h), _mm512_cvtepi32_pd(i));
    tau[d] = _mm512_cvtpd_ps(
        _mm512_mul_pd(_mm512_mul_pd(_mm512_sub_pd(_mm512_set1_pd(1.0), base), _mm512_set1_pd(g.h[d])), inv_r));
  }
  const __mmask8 one_cell = _mm256_cmpeq_epi32_mask(extra, _mm256_setzero_si256());
  const __mmask8 countable =
      countable_r & _mm256_cmpeq_epi32_mask(extra, _mm256_set1_epi32(1)) & (g.countable ? 0xFF : 0);
  const __mmask8 counted = inside & countable, fast = inside & one_cell;
  const __m256i path = _mm256_mask_mov_epi32(_mm256_maskz_mov_epi32(counted, two), ~(counted | fast),
                                             _mm256_set1_epi32(QuickWindows::general));
  const __m512d volume = _mm512_mul_pd(_mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(k4pi3), r), r), r);
  using v8u = std::uint64_t __attribute__((vector_size(64)));
  v8u keys;
  for (int l = 0; l < 8; ++l) keys[l] = pa.rotation_key(p + l);
  kernels::rotation_bank_slots(keys, g.seed);
  const __m256i slot = _mm512_cvtepi64_epi32(reinterpret_cast<__m512i&>(keys));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.path + k), path);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.cell + k), cell);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.slot + k), slot);
  for (int d = 0; d < 3; ++d) _mm256_storeu_ps(out.tau[d] + k, tau[d]);
  _mm512_storeu_pd(out.volume + k, volume);
}

// The same for AVX-512: packed spheres eight a step (plan_eight_packed), others four, where
// the rotation slots' 64-bit products are one instruction each instead of AVX2's three
// 32-bit ones and their shifts (docs/performance.md).
__attribute__((target("arch=x86-64-v4"))) void plan_all_v4(const ParticleArrays& pa, std::int64_t first,
                                                            std::int64_t count, const QuickGrid& g, QuickWindows& out) {
  if (!packed(pa)) return plan_block<false>(pa, first, count, g, out);
  std::int64_t k = 0;
  for (; k + 8 <= count; k += 8) plan_eight_packed(pa, first + k, g, out, k);
  for (; k + 4 <= count; k += 4) plan_four<true>(pa, first + k, 4, g, out, k);
  if (k < count) plan_four<true>(pa, first + k, static_cast<int>(count - k), g, out, k);
}
bool has_v4() {
  static const bool yes = __builtin_cpu_supports("x86-64-v4");
  return yes;
}
#endif

}  // namespace

void plan_sphere_windows(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const QuickGrid& g,
                         QuickWindows& out, [[maybe_unused]] PlanBuild build) {
#ifdef VFE_HAS_V3_BUILD
  if (build == PlanBuild::fastest && has_v4()) return plan_all_v4(pa, first, count, g, out);
  if ((build == PlanBuild::fastest || build == PlanBuild::avx2) && cpu_has_x86_64_v3())
    return plan_all_v3(pa, first, count, g, out);
#endif
  plan_all(pa, first, count, g, out);
}

}  // namespace vfe::detail

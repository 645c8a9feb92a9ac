#include "pmm_plan.hpp"

#include <cstring>

namespace vfe::detail {
namespace {

// GCC's vector types: one source for both builds, the same operations on every lane.
using v4d = double __attribute__((vector_size(32)));
using v4l = std::int64_t __attribute__((vector_size(32)));
using v4i = std::int32_t __attribute__((vector_size(16)));
using v4f = float __attribute__((vector_size(16)));

inline double read_double(const char* p) {
  double x;
  std::memcpy(&x, p, sizeof x);
  return x;
}

/// Four spheres (lanes past `lanes` repeat the last) per step, from entry k of out. Per axis
/// the operations of PmmQuick in the same order: a = (c - half - o) / h and
/// b = (c + half - o) / h as products with 1 / h, their truncations (a >= 0 is checked
/// first), and tau = (1 - ((c - o) / h - lo)) h / r rounded to float.
[[gnu::always_inline]] inline void plan_four(const ParticleArrays& pa, std::int64_t p, int lanes, const QuickGrid& g,
                                             QuickWindows& out, std::int64_t k) {
  const char* c[4];
  const char* rp[4];
  for (int l = 0; l < 4; ++l) {
    const std::int64_t q = p + (l < lanes ? l : lanes - 1);
    c[l] = pa.centres + q * pa.centres_stride;
    rp[l] = pa.radii + q * pa.radii_stride;
  }
  // The hardware prefetcher does not keep up with the particle stream here.
  __builtin_prefetch(c[0] + 16 * pa.centres_stride);
  __builtin_prefetch(c[0] + 16 * pa.centres_stride + 64);
  __builtin_prefetch(rp[0] + 16 * pa.radii_stride);
  const v4d r = {read_double(rp[0]), read_double(rp[1]), read_double(rp[2]), read_double(rp[3])};
  const v4d half = r * g.reach;
  const v4d inv_r = 1.0 / r;
  v4l inside = v4l{} - 1;
  v4i extra = v4i{}, two = v4i{}, cell = v4i{};
  v4f tau[3];
  const std::int32_t stride[3] = {1, g.nx, g.nxy};
  for (int d = 0; d < 3; ++d) {
    const v4d x = {read_double(c[0] + 8 * d), read_double(c[1] + 8 * d), read_double(c[2] + 8 * d),
                   read_double(c[3] + 8 * d)};
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
  const v4i in = __builtin_convertvector(inside, v4i), counts = __builtin_convertvector((v4l)(r > g.min_radius), v4i);
  const v4i one = v4i{} + 1;
  const v4i countable = counts & (extra == one) & (g.countable ? v4i{} - 1 : v4i{});
  const v4i kind = in & (((extra == 0) & std::int32_t{QuickWindows::fast}) | (countable & std::int32_t{QuickWindows::count}));
  std::memcpy(out.kind + k, &kind, sizeof kind);
  std::memcpy(out.two + k, &two, sizeof two);
  std::memcpy(out.cell + k, &cell, sizeof cell);
  for (int d = 0; d < 3; ++d) std::memcpy(out.tau[d] + k, &tau[d], sizeof tau[d]);
}

void plan_all(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const QuickGrid& g,
              QuickWindows& out) {
  std::int64_t k = 0;
  for (; k + 4 <= count; k += 4) plan_four(pa, first + k, 4, g, out, k);
  if (k < count) plan_four(pa, first + k, static_cast<int>(count - k), g, out, k);
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VFE_PLAN_V3 1
__attribute__((target("arch=x86-64-v3"))) void plan_all_v3(const ParticleArrays& pa, std::int64_t first,
                                                            std::int64_t count, const QuickGrid& g, QuickWindows& out) {
  std::int64_t k = 0;
  for (; k + 4 <= count; k += 4) plan_four(pa, first + k, 4, g, out, k);
  if (k < count) plan_four(pa, first + k, static_cast<int>(count - k), g, out, k);
}
bool has_v3() {
  static const bool yes = __builtin_cpu_supports("x86-64-v3");
  return yes;
}
#endif

}  // namespace

void plan_sphere_windows(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const QuickGrid& g,
                         QuickWindows& out, [[maybe_unused]] PlanBuild build) {
#ifdef VFE_PLAN_V3
  if (build == PlanBuild::fastest && has_v3()) return plan_all_v3(pa, first, count, g, out);
#endif
  plan_all(pa, first, count, g, out);
}

}  // namespace vfe::detail

// pmm's block planning (engine/src/pmm_plan.hpp) against a one-sphere-at-a-time oracle
// written from PmmQuick's rules: the window's cells floor((c -+ half - o) / h) per axis from
// the products with 1 / h, general when it reaches beyond the grid, the fast path for one
// cell, a count for at most two per axis with tau = (1 - ((c - o) / h - lo)) h / r in
// float; each counted sphere's rotation slot (kernels::rotation_bank_slot of its rotation
// key) and each sphere's volume (sphere_volume). Every build (baseline x86-64, AVX2 and
// the fastest the CPU has) must give the oracle's decisions bit for bit, for every block
// length, packed and strided arrays, with and without host ids, and windows whose bounds
// fall exactly on faces or on the grid's boundary.
#include "pmm_plan.hpp"

#include <vfe/kernels/particle_template.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

namespace vfe::test {
namespace {

using detail::ParticleArrays;
using detail::PlanBuild;
using detail::QuickGrid;
using detail::QuickWindows;

QuickGrid make_grid() {
  QuickGrid g{};
  const double origin[3] = {-1.25, 0.5, 3.0}, h[3] = {0.5, 0.25, 1.0 / 3.0};
  const std::int32_t n[3] = {12, 20, 9};
  for (int d = 0; d < 3; ++d) {
    g.origin[d] = origin[d];
    g.h[d] = h[d];
    g.inv_h[d] = 1.0 / h[d];
    g.hi_bound[d] = n[d];
  }
  g.reach = 0.97;
  g.min_radius = 1e-6 * 0.5;
  g.countable = true;
  g.nx = n[0];
  g.nxy = n[0] * n[1];
  g.seed = 0x5eed;
  return g;
}

/// The oracle: one sphere's decision by the rules above, in scalar double.
struct Expected {
  std::int32_t path, cell;
  float tau[3];
};
Expected oracle(const QuickGrid& g, const double* c, double r) {
  Expected e{QuickWindows::general, 0, {0, 0, 0}};
  const double half = r * g.reach;
  std::int64_t lo[3], extra = 0, two = 0;
  for (int d = 0; d < 3; ++d) {
    const double a = (c[d] - half - g.origin[d]) * g.inv_h[d], b = (c[d] + half - g.origin[d]) * g.inv_h[d];
    if (!(a >= 0 && b < g.hi_bound[d])) return e;
    lo[d] = static_cast<std::int64_t>(std::floor(a));
    const std::int64_t j = static_cast<std::int64_t>(std::floor(b));
    extra |= j - lo[d];
    two |= (j - lo[d]) << d;
  }
  e.cell = static_cast<std::int32_t>(lo[0] + g.nx * lo[1] + g.nxy * lo[2]);
  if (extra == 0) {
    e.path = QuickWindows::fast;
    return e;
  }
  if (extra > 1 || !(r > g.min_radius) || !g.countable) return e;
  e.path = static_cast<std::int32_t>(two);  // counted: its split set, 1 to 7
  for (int d = 0; d < 3; ++d) {
    const double base = (c[d] - g.origin[d]) * g.inv_h[d] - double(lo[d]);
    e.tau[d] = static_cast<float>((1.0 - base) * g.h[d] * (1.0 / r));
  }
  return e;
}

/// Spheres as records of `stride` doubles (x, y, z, r first), and host ids (large, so the
/// hash's 64-bit products matter); `packed`: the same spheres as the packed arrays a host
/// passes most often (centres 3n doubles, radii n), which the planning loads its own way.
struct Spheres {
  std::vector<double> records, centres, radii;
  std::vector<std::int64_t> ids;
  int stride = 4;
  bool with_ids = false, packed = false;
  std::int64_t n() const { return static_cast<std::int64_t>(records.size()) / stride; }
  void add(double x, double y, double z, double r) {
    records.insert(records.end(), {x, y, z, r});
    records.resize(records.size() + static_cast<std::size_t>(stride - 4), -7.0);
    centres.insert(centres.end(), {x, y, z});
    radii.push_back(r);
    ids.push_back(std::int64_t(0x7654321) * static_cast<std::int64_t>(ids.size()) + 0x123456789abcll);
  }
  ParticleArrays arrays() const {
    ParticleArrays pa;
    pa.n = n();
    pa.centres = reinterpret_cast<const char*>(packed ? centres.data() : records.data());
    pa.centres_stride = packed ? 24 : 8 * stride;
    pa.radii = reinterpret_cast<const char*>(packed ? radii.data() : records.data() + 3);
    pa.radii_stride = packed ? 8 : 8 * stride;
    if (with_ids) pa.ids = reinterpret_cast<const char*>(ids.data());
    return pa;
  }
};

/// Random spheres over the grid and a little beyond, and spheres whose window bound lies
/// exactly on a face or on the grid's far boundary (the products are exact there).
Spheres test_spheres(int stride) {
  const QuickGrid g = make_grid();
  Spheres s;
  s.stride = stride;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 3000; ++i) {
    double c[3];
    for (int d = 0; d < 3; ++d) c[d] = g.origin[d] + (1.2 * u(rng) - 0.1) * g.hi_bound[d] * g.h[d];
    const double r = (i % 7 == 0 ? 0.02 : 0.05 + 0.4 * u(rng)) * (i % 11 == 0 ? 1e-7 : 1.0);
    s.add(c[0], c[1], c[2], r);
  }
  // Bounds on faces: r = 0.25 / reach gives half = 0.25 (binary), h_x = 0.5.
  const double r = 0.25 / g.reach;
  for (int k = 0; k < 12; ++k) {
    const double x = g.origin[0] + 0.5 * k + 0.25 * (k % 3 - 1);  // a or b exactly on a face
    s.add(x, 2.0, 4.0, r);
    s.add(x, 2.0, 4.0, std::nextafter(r, 1.0));
    s.add(x, 2.0, 4.0, std::nextafter(r, 0.0));
  }
  s.add(g.origin[0] + 0.25 * 1, 2.0, 4.0, r);                      // a = 0 exactly: inside
  s.add(g.origin[0] + g.hi_bound[0] * 0.5 - 0.25, 2.0, 4.0, r);    // b = n exactly: beyond
  return s;
}

void expect_oracle(const Spheres& s, PlanBuild build, std::int64_t block) {
  const QuickGrid g = make_grid();
  const ParticleArrays pa = s.arrays();
  int fast = 0, count = 0, general = 0;
  for (std::int64_t first = 0; first < pa.n; first += block) {
    const std::int64_t m = std::min(block, pa.n - first);
    auto w = std::make_unique<QuickWindows>();
    detail::plan_sphere_windows(pa, first, m, g, *w, build);
    for (std::int64_t i = 0; i < m; ++i) {
      const std::int64_t k = i;
      const double* rec = s.records.data() + (first + k) * s.stride;
      const Expected e = oracle(g, rec, rec[3]);
      ASSERT_EQ(w->path[i], e.path) << "sphere " << first + k;
      const bool counted = e.path > QuickWindows::fast && e.path < QuickWindows::general;
      fast += e.path == QuickWindows::fast, count += counted;
      general += e.path == QuickWindows::general;
      if (e.path == QuickWindows::general) continue;
      ASSERT_EQ(w->cell[i], e.cell) << "sphere " << first + k;
      const double volume = 4.0 / 3.0 * std::numbers::pi * rec[3] * rec[3] * rec[3];
      ASSERT_EQ(std::memcmp(&w->volume[i], &volume, sizeof volume), 0) << "sphere " << first + k;
      if (!counted) continue;
      const std::size_t slot = kernels::rotation_bank_slot(pa.rotation_key(first + k), g.seed);
      ASSERT_EQ(w->slot[i], static_cast<std::int32_t>(slot)) << "sphere " << first + k;
      for (int d = 0; d < 3; ++d) {
        float got = w->tau[d][i];
        ASSERT_EQ(std::memcmp(&got, &e.tau[d], sizeof got), 0) << "sphere " << first + k << " axis " << d;
      }
    }
  }
  // Every kind of decision is exercised.
  EXPECT_GT(fast, 100);
  EXPECT_GT(count, 300);
  EXPECT_GT(general, 100);
}

TEST(PmmPlan, BothBuildsGiveTheOneSphereDecisionsBitForBit) {
  for (const int stride : {4, 5, 0})  // 0: packed arrays
    for (const bool ids : {false, true})
      for (const PlanBuild build : {PlanBuild::fastest, PlanBuild::baseline, PlanBuild::avx2})
        for (const std::int64_t block : {std::int64_t(1), std::int64_t(3), std::int64_t(4), std::int64_t(7),
                                         std::int64_t(16), std::int64_t(37), detail::kQuickSpheres}) {
          SCOPED_TRACE((stride ? "stride " + std::to_string(stride) : std::string("packed")) + (ids ? " ids" : "") +
                       (build == PlanBuild::fastest    ? " fastest"
                        : build == PlanBuild::baseline ? " baseline"
                                                       : " avx2") +
                       " block " + std::to_string(block));
          Spheres s = test_spheres(stride ? stride : 4);
          s.with_ids = ids;
          s.packed = stride == 0;
          expect_oracle(s, build, block);
        }
}

TEST(PmmPlan, ATemplateThatCannotBeCountedIsNeverCounted) {
  QuickGrid g = make_grid();
  g.countable = false;
  const Spheres s = test_spheres(4);
  const ParticleArrays pa = s.arrays();
  int fast = 0;
  auto w = std::make_unique<QuickWindows>();
  for (std::int64_t first = 0; first < pa.n; first += detail::kQuickSpheres) {
    const std::int64_t m = std::min(detail::kQuickSpheres, pa.n - first);
    detail::plan_sphere_windows(pa, first, m, g, *w);
    for (std::int64_t i = 0; i < m; ++i) {
      ASSERT_TRUE(w->path[i] == QuickWindows::fast || w->path[i] == QuickWindows::general);
      fast += w->path[i] == QuickWindows::fast;
    }
  }
  EXPECT_GT(fast, 100);
}

}  // namespace
}  // namespace vfe::test

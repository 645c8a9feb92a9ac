// pmm's quick cases decided for several spheres at once: each sphere's path (fast, counted
// on a set of split axes, or general), window of cells and, where it spans at most two cells
// per axis, the thresholds of its octant count (methods/driver.hpp, PmmQuick), with each
// counted sphere's rotation slot and each sphere's volume, four (packed spheres with AVX-512:
// eight) spheres a step, built for baseline x86-64, x86-64-v3 and x86-64-v4 (the newest the
// CPU has is used) with the same results as one sphere at a time.
#pragma once

#include "particle_arrays.hpp"

#include <cstdint>

namespace vfe::detail {

/// A Cartesian grid from its origin (not a block, fewer than 2^31 cells) as the planning
/// reads it, and the one template's reach.
struct QuickGrid {
  double origin[3], inv_h[3], h[3], hi_bound[3];  ///< hi_bound: the cell count per axis
  double reach;       ///< of the template, in radii
  double min_radius;  ///< counting needs r above this
  bool countable;     ///< the template can be counted per octant
  std::int32_t nx, nxy;
  std::uint64_t seed;  ///< orientation=random's seed: the rotation bank's slots
};

/// The quick cases of up to kQuickSpheres spheres, entry i for sphere first + i.
inline constexpr std::int64_t kQuickSpheres = 256;
struct QuickWindows {
  /// A sphere's path: fast (its window is one cell), a set of split axes 1 to 7 (counted per
  /// octant; bit d set when the window has two cells along d), or general. One number, so
  /// finish_chunk sorts the spheres by it without a branch.
  enum Path : std::int32_t { fast = 0, general = 8 };
  std::int32_t path[kQuickSpheres];
  std::int32_t cell[kQuickSpheres];  ///< fast or counted: the window's first cell
  std::int32_t slot[kQuickSpheres];  ///< counted: the rotation bank's slot of the sphere's rotation key
  float tau[3][kQuickSpheres];       ///< counted: the thresholds per axis (PmmQuick's)
  double volume[kQuickSpheres];      ///< fast or counted: the sphere's volume (sphere_volume's rounding)
};

/// Which build runs: the fastest the CPU has, baseline x86-64, or AVX2 (x86-64-v3) where the
/// CPU has it, else baseline (the tests compare them).
enum class PlanBuild { fastest, baseline, avx2 };

/// The quick cases of spheres [first, first + count) of pa (count <= kQuickSpheres), sphere
/// first + i in entry i of out: PmmQuick's decisions, bit for bit, with each counted
/// sphere's rotation slot (kernels::rotation_bank_slot of pa.rotation_key and g.seed) and
/// each sphere's volume.
void plan_sphere_windows(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const QuickGrid& g,
                         QuickWindows& out, PlanBuild build = PlanBuild::fastest);

}  // namespace vfe::detail

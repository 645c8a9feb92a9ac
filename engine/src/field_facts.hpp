// What a compute's report says of its field: the solid volume it holds, the volume that
// clipping at alpha_min removes, and the cells holding more solid than their volume. The
// engine adds these block by block while the merge has the block in the cache.
#pragma once

#include "sphere_lanes.hpp"

#include <cstdint>
#include <cstring>

namespace vfe::detail {

struct FieldFacts {
  double sum = 0, clipped = 0, overfull_volume = 0;
  std::int64_t overfull_cells = 0;
  void add(const FieldFacts& o) {
    sum += o.sum, clipped += o.clipped, overfull_volume += o.overfull_volume, overfull_cells += o.overfull_cells;
  }
};

/// Adds cells [begin, end) of field f to facts; cell_volume(c) gives V_c. clipped: the sum
/// of max(0, f - (1 - alpha_min) V) when alpha_min > 0; overfull: cells with f - V > 1e-12 V.
/// Four running sums as the lanes of a vector, cell c in lane (c - begin) mod 4, the lanes
/// added in order at the end: one chain of adds would cost an add's latency per cell. No
/// branch: a field may have many overfull cells, scattered.
template <class CellVolume>
[[gnu::always_inline]] inline void add_field_facts(const double* f, std::int64_t begin, std::int64_t end,
                                                   CellVolume&& cell_volume, double alpha_min, FieldFacts& facts) {
  using lanes::v4d;
  using lanes::v4l;
  const double keep = 1.0 - alpha_min;  // of a cell's volume, what clipping leaves solid
  const bool clip = alpha_min > 0;
  v4d sum{}, clipped{}, overfull{};
  v4l overfull_cells{};
  auto add = [&](const v4d& x, const v4d& v, const v4l& lane) __attribute__((always_inline)) {
    sum += (v4d)((v4l)x & lane);
    const v4d kept = x - keep * v, excess = x - v;
    if (clip) clipped += (v4d)((v4l)kept & (kept > 0.0) & lane);
    const v4l over = (excess > 1e-12 * v) & lane;
    overfull_cells -= over;
    overfull += (v4d)((v4l)excess & over);
  };
  std::int64_t c = begin;
  for (; c + 4 <= end; c += 4) {
    v4d x;
    std::memcpy(&x, f + c, sizeof x);
    add(x, v4d{cell_volume(c), cell_volume(c + 1), cell_volume(c + 2), cell_volume(c + 3)}, v4l{} - 1);
  }
  if (c < end) {
    v4d x{}, v{};
    v4l lane{};
    for (int l = 0; c + l < end; ++l) x[l] = f[c + l], v[l] = cell_volume(c + l), lane[l] = -1;
    add(x, v, lane);
  }
  facts.sum += (sum[0] + sum[1]) + (sum[2] + sum[3]);
  facts.clipped += (clipped[0] + clipped[1]) + (clipped[2] + clipped[3]);
  facts.overfull_volume += (overfull[0] + overfull[1]) + (overfull[2] + overfull[3]);
  facts.overfull_cells += (overfull_cells[0] + overfull_cells[1]) + (overfull_cells[2] + overfull_cells[3]);
}

/// add_field_facts with one volume for every cell (a Cartesian grid), in the fastest
/// build the CPU has (the same sums in every build).
void add_uniform_field_facts(const double* f, std::int64_t begin, std::int64_t end, double volume, double alpha_min,
                             FieldFacts& facts);

}  // namespace vfe::detail

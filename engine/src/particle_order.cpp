#include "particle_order.hpp"

#include "sphere_pass.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <limits>

namespace vfe::detail {

namespace {

/// Particles per range of the two passes: fixed, so the order (by block, then by host
/// index) is the same for any thread count.
constexpr std::int64_t kRange = 1 << 16;

/// The slab of a centre's z: [0, blocks), those beyond the box (and NaN) in the end slabs.
struct Slabs {
  double lo, per_length;
  double last;
  std::int64_t of(double z) const {
    double t = (z - lo) * per_length;
    t = t > 0 ? t : 0;  // NaN too
    return static_cast<std::int64_t>(t < last ? t : last);
  }
};

}  // namespace

std::int64_t order_blocks(const Options& o, const ParticleArrays& pa, bool cartesian, std::int64_t cells,
                          std::int64_t layers) {
  if (o.particle_order == ParticleOrder::input || pa.n == 0 || pa.shape_ids ||
      o.orientation == Orientation::given || o.incremental || o.weights)
    return 0;
  const std::int64_t bytes = 8 * cells;
  if (o.particle_order == ParticleOrder::automatic &&
      !(cartesian && o.method != Method::direct && bytes >= kAutoFieldBytes && pa.n >= kAutoParticles))
    return 0;
  std::int64_t blocks = std::min<std::int64_t>((bytes + kBlockBytes - 1) / kBlockBytes, 4096);
  if (o.particle_order == ParticleOrder::blocked) blocks = std::max<std::int64_t>(blocks, 2);  // asked for: even when small
  if (layers > 0) blocks = std::min(blocks, layers);
  return blocks >= 2 ? blocks : 0;
}

ParticleArrays BlockedOrder::arrange(tbb::task_arena& arena, const ParticleArrays& pa, double lo, double hi,
                                      std::int64_t blocks) {
  const std::int64_t n = pa.n;
  const std::int64_t ranges = (n + kRange - 1) / kRange;
  const Slabs slabs{lo, double(blocks) / (hi - lo), double(blocks - 1)};
  counts_.assign(static_cast<std::size_t>(ranges * blocks), 0);
  bad_.assign(static_cast<std::size_t>(ranges), 0);
  const char* const centres = pa.centres;
  const std::int64_t cs = pa.centres_stride;
  auto z_of = [&](std::int64_t p) { return reinterpret_cast<const double*>(centres + p * cs)[2]; };

  // Pass 1: validation's checks and the particles per (range, block).
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), ranges, [&](std::int64_t r) {
      std::int64_t* count = &counts_[static_cast<std::size_t>(r * blocks)];
      const std::int64_t end = std::min(n, (r + 1) * kRange);
      constexpr double inf = std::numeric_limits<double>::infinity();
      const SphereBounds open{{-inf, -inf, -inf}, {inf, inf, inf}};
      Validation v;
      bool good = true;
      for (std::int64_t first = r * kRange; first < end; first += kSphereChunk) {
        const std::int64_t k_end = std::min(kSphereChunk, end - first);
        // A bad chunk leaves the order as it is (the compute then fails): its values are not
        // taken into slabs (a NaN compared would raise an exception a host may trap).
        if (!check_sphere_chunk(pa, first, k_end, open, v)) {
          good = false;
          continue;
        }
        for (std::int64_t k = 0; k < k_end; ++k) ++count[slabs.of(z_of(first + k))];
      }
      bad_[static_cast<std::size_t>(r)] = !good;
    });
  });
  if (std::find(bad_.begin(), bad_.end(), 1) != bad_.end()) return pa;

  // Exclusive scan, block by block and within a block range by range: a stable order.
  std::int64_t at = 0;
  for (std::int64_t b = 0; b < blocks; ++b)
    for (std::int64_t r = 0; r < ranges; ++r) {
      std::int64_t& c = counts_[static_cast<std::size_t>(r * blocks + b)];
      const std::int64_t here = c;
      c = at;
      at += here;
    }

  // Pass 2: each particle's record to its block's next position.
  const std::int64_t width = pa.ids ? 6 : 5;
  if (records_.size() < static_cast<std::size_t>(n * width)) records_.resize(static_cast<std::size_t>(n * width));
  double* const records = records_.data();
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), ranges, [&](std::int64_t r) {
      std::int64_t* next = &counts_[static_cast<std::size_t>(r * blocks)];
      const std::int64_t end = std::min(n, (r + 1) * kRange);
      for (std::int64_t p = r * kRange; p < end; ++p) {
        __builtin_prefetch(centres + (p + 16) * cs);
        __builtin_prefetch(pa.radii + (p + 16) * pa.radii_stride);
        const double* c = reinterpret_cast<const double*>(centres + p * cs);
        double* rec = records + next[slabs.of(c[2])]++ * width;
        rec[0] = c[0], rec[1] = c[1], rec[2] = c[2], rec[3] = pa.radius(p);
        std::memcpy(rec + 4, &p, sizeof p);
        if (pa.ids) std::memcpy(rec + 5, pa.ids + p * pa.ids_stride, sizeof(std::int64_t));
      }
    });
  });

  ParticleArrays out;
  out.n = n;
  const char* base = reinterpret_cast<const char*>(records);
  const std::int64_t stride = 8 * width;
  out.centres = base, out.centres_stride = stride;
  out.radii = base + 24, out.radii_stride = stride;
  out.host_index = base + 32, out.host_index_stride = stride;
  out.ids = base + (pa.ids ? 40 : 32), out.ids_stride = stride;  // the rotation key: the host's id, else its index
  return out;
}

}  // namespace vfe::detail

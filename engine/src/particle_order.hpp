// particle_order=blocked: the host's spheres copied into cell-block order before a compute.
//
// A DEM code's particles lie in no spatial order, so each deposit lands somewhere else in
// the field; once a thread's field outgrows its core's L2, every deposit is a cache miss.
// The field is split into slabs along the mesh's slowest axis (z: a slab of a grid is one
// contiguous slice of the field, of about kBlockBytes), and the particles are bucketed by
// the slab of their centre with a stable counting sort (count, scan, permute) into compact
// records: two sequential passes over the host's arrays and a few hundred write streams,
// where a full spatial sort would read the particles as scattered as the deposits are. The
// method's pass then walks the records bucket by bucket, its deposits within one slab.
//
// Each record keeps the host's index (errors, the driver's particle index) and the rotation
// key (the host's id, else the index), so results equal the host order's up to the order of
// summation, and bitwise with deterministic=1 (fixed-point sums).
#pragma once

#include "options.hpp"
#include "particle_arrays.hpp"

#include <tbb/task_arena.h>

#include <cstdint>
#include <vector>

namespace vfe::detail {

/// Bytes of one thread's field a block aims at: a sixteenth of this machine's 1 MB per-core
/// L2, so the slab, the record stream and the method's own data stay in it (at 4e6 spheres,
/// chi = 2, slabs of 256, 64 and 16 KB (one cell layer) measured alike within the noise).
inline constexpr std::int64_t kBlockBytes = 64 * 1024;

/// particle_order=auto orders the particles when one thread's field is at least this large
/// (at 1 MB, the L2's size, the copy costs about what it saves; at 1.9 and 3.8 MB every
/// method but direct gains 1.1-2x: docs/performance.md, "Particle order").
inline constexpr std::int64_t kAutoFieldBytes = 3 * 512 * 1024;
/// ... and there are at least this many particles (the copy's fixed costs).
inline constexpr std::int64_t kAutoParticles = 1 << 17;

/// The slabs particle_order gives this compute, 0 for the host's order: a field of `cells`
/// doubles with `layers` cell layers along z (0: a polyMesh, whose cells have no layers)
/// in slabs of about kBlockBytes, at most one per layer. Spheres only, without given
/// orientations (the records hold none), and not with incremental or weights (they keep
/// deposits by the host's index). auto: only on a Cartesian grid (`cartesian`), from
/// kAutoFieldBytes and kAutoParticles on, and not for direct (its fused pass costs about
/// one read of the particles, which the copy alone costs twice).
std::int64_t order_blocks(const Options& o, const ParticleArrays& pa, bool cartesian, std::int64_t cells,
                          std::int64_t layers);

class BlockedOrder {
 public:
  /// Copies pa's spheres (no orientations, no shapes) into `blocks` slabs of [lo, hi) along
  /// z, in the arena, and returns them as arrays whose host(p) is the host's index. Returns
  /// pa itself when a particle fails validation's checks, so validation names it by the
  /// host's index.
  ParticleArrays arrange(tbb::task_arena& arena, const ParticleArrays& pa, double lo, double hi,
                         std::int64_t blocks);

 private:
  std::vector<double> records_;       ///< per particle x, y, z, r, host index (, host id)
  std::vector<std::int64_t> counts_;  ///< per range and block: particles, then write positions
  std::vector<std::uint8_t> bad_;     ///< per range: some particle failed the checks
};

}  // namespace vfe::detail

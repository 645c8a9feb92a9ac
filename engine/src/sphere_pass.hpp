// The spheres' validation, and direct's deposit at each centre's cell in the same pass:
// one loop over a chunk of particles, four at a time, compiled for baseline x86-64 and
// for x86-64-v3 (used when the CPU has it) with the same results.
#pragma once

#include "particle_arrays.hpp"

#include <cstdint>

namespace vfe::detail {

class BinWriter;

/// Particles per call of the passes below: a chunk's particles left to the caller fit a
/// buffer of this size on the stack.
inline constexpr std::int64_t kSphereChunk = 256;

/// A Cartesian grid of fewer than kCentreGridCells cells as direct's pass locates centres:
/// cell (i, j, k) with i = floor((x - origin) * inv_spacing) in [0, cells) per axis, at
/// i + strides[0] j + strides[1] k of field (the pass computes in 32-bit integers).
struct CentreGrid {
  double origin[3], inv_spacing[3], cells[3];
  std::int32_t strides[2];
  double* field;  ///< the thread's field
  BinWriter* bins = nullptr;  ///< instead of field: the thread's bins (cell_bins.hpp)
  /// Grid cell -> field index (a polyMesh's box lattice, BoxLattice::cell_map); null: the
  /// grid's own index.
  const std::int64_t* cell_map = nullptr;
};
inline constexpr std::int64_t kCentreGridCells = std::int64_t(1) << 31;

/// Which build of the pass runs: the fastest the CPU has, or baseline x86-64 (the tests
/// compare the two).
enum class PassBuild { fastest, baseline };

/// Checks spheres [first, first + count) into a (count <= kSphereChunk): NaN, infinities,
/// r <= 0 and volumes doubles cannot hold (particle_values_ok), the volume summed in
/// particle order, d_min, d_max and the spheres beyond b. A chunk holding a bad particle
/// is checked again one by one: a.first_bad names its first. Returns whether every sphere
/// of the chunk is good.
bool check_sphere_chunk(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const SphereBounds& b,
                        Validation& a, PassBuild build = PassBuild::fastest);

/// check_sphere_chunk, and each sphere whose centre lies in g adds its volume to its cell
/// of g.field or g.bins (renumbered by g.cell_map). Returns how many spheres it left to the caller, their indices in
/// left[0 ..): centres outside the grid, in order. A chunk holding a bad particle returns
/// 0 (the compute fails; what it added lies within the field, to be dropped).
std::int64_t deposit_sphere_chunk(const ParticleArrays& pa, std::int64_t first, std::int64_t count,
                                  const SphereBounds& b, const CentreGrid& g, Validation& a, std::int64_t* left,
                                  PassBuild build = PassBuild::fastest);

}  // namespace vfe::detail

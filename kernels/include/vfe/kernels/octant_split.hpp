// PMM by counting instead of scattering: when a particle's window of cells has at most two
// cells per axis, a sub-element's cell is fixed by which side of each split plane (the face
// between the two cells of an axis) its centroid lies on. Per split axis one comparison
// per point gives a bit mask over the template, and the sub-elements of each of the eight
// octants are a popcount of three masks. The comparisons run in float; a point too near a
// plane for float to decide makes the caller locate that particle in double, so every
// sub-element lands in the cell the straightforward locate gives it. A template of more
// than 512 points is kept in groups of eight near one another: a plane that misses a
// group's bounding ball settles its eight points with one comparison.
#pragma once

#include <vfe/kernels/particle_template.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>

namespace vfe::kernels {

/// Points within this distance of a split plane (template units: the unit sphere) are
/// left to double arithmetic. Float's error on R_d . q and on the threshold is below 1e-6.
inline constexpr double kSplitGuard = 0x1p-18;  // 3.8e-6

/// The float points are stored times this (a power of two: exact), so that the rounded
/// distance to a plane in these units is 0 exactly for a point within the guard band.
inline constexpr double kSplitScale = 0.5 / kSplitGuard;

/// Most points the counting path takes (64 words of 64); larger templates scatter.
inline constexpr std::size_t kMaxSplitWords = 64;

/// Templates of up to this many words of 64 points are compared point by point; larger ones
/// are kept in groups of eight with a ball each (ParticleTemplate::split_groups).
inline constexpr std::size_t kMostUngroupedWords = 8;

/// Fills t.split_points when every sub-element has the same share and the template has at
/// most kMaxSplitWords x 64 points; otherwise leaves them empty.
void prepare_octant_split(ParticleTemplate& t);

/// Which code counts: the fastest the CPU runs (AVX2 + FMA on x86-64 when present), or the
/// portable one (tests run both).
enum class SplitPath { fastest, portable };

/// The count for one set of split axes: rows is R as floats row by row, tau[d] the
/// threshold of split axis d (entries of other axes are not read); the rest as
/// count_octants. Each set has its own code, so a particle pays no dispatch or set-up.
using OctantCountFn = bool (*)(const ParticleTemplate& t, const float* rows, const float tau[3],
                               std::int32_t counts[8]);

/// One particle of a batch: its rotation and its thresholds (as OctantCountFn's). The
/// rotation is its rows as floats (9 values) for batch_by_split, or its slot's projections
/// of the template (BankProjections::of_slot) for projected_batch_by_split.
struct OctantQuery {
  const float* rotation;
  float tau[3];
};

/// Floats per row of BankProjections for a template of n points: whole groups of eight (the
/// last padded by repeating the last point).
constexpr std::size_t projection_row(std::size_t n) { return 8 * ((n + 7) / 8); }

/// The template's points on each row of each rotation of the bank (kRotationBankSize; what
/// pmm takes with orientation=random), times kSplitScale, each computed in double and
/// rounded to float once: a count then loads a point's distance to a plane instead of
/// computing it from the rotation. For templates of at most 64 points (split_words 1):
/// per slot, row 0's projection_row(n) values (the points in split_points' order), then
/// row 1's, then row 2's, slot after slot, from a 64-byte boundary. 4096 x 3 x 48 floats
/// (2.4 MB) for 45 points.
struct BankProjections {
  struct Free {
    void operator()(float* p) const { ::operator delete[](p, std::align_val_t{64}); }
  };
  std::unique_ptr<float[], Free> values;
  std::size_t row = 0;  ///< floats per row: projection_row of the template's size

  /// Slot k's three rows of projections.
  const float* of_slot(std::size_t slot) const { return values.get() + slot * 3 * row; }
  explicit operator bool() const { return row != 0; }
};

/// t's BankProjections; empty where t has no split points or more than 64 points.
BankProjections project_on_rotation_bank(const ParticleTemplate& t);

/// The count for n particles of one set of split axes, one after another in one call:
/// counts[8 k + o] and decided[k] (1, or 0 where OctantCountFn returns false, counts then
/// undefined) for queries[k]. The same results as n calls, for less per particle.
using OctantBatchFn = void (*)(const ParticleTemplate& t, const OctantQuery* queries, std::size_t n,
                               std::int32_t* counts, std::uint8_t* decided);

/// The counting code per split mask (entry `split`, 1 to 7; entry 0 puts every point in
/// octant 0) for template t (a template of at most 64 points has code for its size) on a
/// path; look it up once per template, not per particle. projected_batch_by_split takes
/// queries whose rotation is the template's BankProjections of the particle's slot (null
/// entries where t has none: more than 64 points). Where both decide, they give the same
/// counts (the double count); both refuse a point within the guard band, and their float
/// errors are far below it, so their refusals can differ only for a point at its edge.
struct OctantCounter {
  OctantCountFn by_split[8];
  OctantBatchFn batch_by_split[8];
  OctantBatchFn projected_batch_by_split[8];
};
const OctantCounter& octant_counter(const ParticleTemplate& t, SplitPath path = SplitPath::fastest);

/// Sub-elements per octant: point q (of t) is above the plane of axis d when
/// R.row(d) . q >= tau[d], for each axis d with bit d set in `split`; axes not split put
/// every point below. counts[bx + 2 by + 4 bz] receives the points on sides (bx, by, bz).
/// Returns false (counts undefined) when some point lies within kSplitGuard of a split
/// plane. Needs t.split_points and |tau[d]| <= 2.
bool count_octants(const ParticleTemplate& t, const Eigen::Matrix3d& R, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path = SplitPath::fastest);
/// The same with R given as floats, row by row (9 values: each entry of R rounded to float).
bool count_octants(const ParticleTemplate& t, const float* rows, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path = SplitPath::fastest);

}  // namespace vfe::kernels

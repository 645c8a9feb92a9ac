#include <vfe/kernels/octant_split.hpp>
#include <vfe/kernels/point_tree.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <utility>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#define VFE_OCTANT_AVX2 1
#endif

namespace vfe::kernels {

namespace {

/// Orders points [first, last) of `order` so that each run of eight (from first) lies close
/// together: halves of multiples of eight points along the widest axis, down to eight.
void group_points(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& order, std::size_t first,
                  std::size_t last) {
  if (last - first <= 8) return;
  const std::size_t mid = first + 8 * ((last - first + 15) / 16);
  split_along_widest_axis(points, order, first, mid, last, bounds_of(points, order, first, last));
  group_points(points, order, first, mid);
  group_points(points, order, mid, last);
}

}  // namespace

void prepare_octant_split(ParticleTemplate& t) {
  t.split_points.clear();
  t.split_groups.clear();
  t.split_words = 0;
  const std::size_t n = t.size();
  if (n == 0 || n > kMaxSplitWords * 64) return;
  for (const double f : t.fractions)
    if (f != t.fractions[0]) return;
  const std::size_t words = (n + 63) / 64, stride = words * 64;
  // Every point has the same share, so a count does not depend on the points' order: more
  // than kMostUngroupedWords x 64 go in groups of eight near one another, whose bounding
  // balls settle most of them at once.
  const bool grouped = words > kMostUngroupedWords;
  std::vector<std::size_t> order(n);
  for (std::size_t s = 0; s < n; ++s) order[s] = s;
  if (grouped) group_points(t.points, order, 0, n);
  // Padding repeats the last point, masked out of the counts by the counters: a padding
  // lane is near a plane only when that point is, so it never refuses a particle of its own
  // and needs no test (and no NaN: converting or comparing NaN raises the invalid-operation
  // exception, which hosts such as OpenFOAM trap). The scale is a power of two, so it
  // changes no rounding.
  t.split_points.assign(3 * stride, 0.0f);
  for (std::size_t s = 0; s < stride; ++s)
    for (int d = 0; d < 3; ++d)
      t.split_points[d * stride + s] = static_cast<float>(kSplitScale * t.points[order[std::min(s, n - 1)]][d]);
  t.split_words = words;
  if (!grouped) return;
  // Each group's ball: a centre near that of the smallest ball holding its points (a few
  // hundred steps of Badoiu and Clarkson's walk towards the farthest point, from the
  // points' mean), as floats, and the farthest float point's distance from it (in double)
  // grown by 1e-6, which covers the float rotation rows' norm (1 within 1e-7), rounded up;
  // padding groups get zeros and are masked. A ball can be looser than the box, but
  // its reach along any plane normal is that one number: the test of eight groups against
  // a plane costs three products fewer.
  const std::size_t gstride = words * 8;
  t.split_groups.assign(4 * gstride, 0.0f);
  for (std::size_t g = 0; 8 * g < n; ++g) {
    const std::size_t first = 8 * g, end = std::min(n, first + 8);
    auto point = [&](std::size_t s) { return kSplitScale * t.points[order[s]]; };
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (std::size_t s = first; s < end; ++s) centre += point(s);
    centre /= double(end - first);
    for (int step = 1; step <= 300; ++step) {
      Eigen::Vector3d farthest = point(first);
      for (std::size_t s = first + 1; s < end; ++s)
        if ((point(s) - centre).squaredNorm() > (farthest - centre).squaredNorm()) farthest = point(s);
      centre += (farthest - centre) / double(step + 1);
    }
    for (int d = 0; d < 3; ++d) t.split_groups[d * gstride + g] = static_cast<float>(centre[d]);
    double radius = 0;
    for (std::size_t s = first; s < end; ++s) {
      double squared = 0;
      for (int d = 0; d < 3; ++d) {
        const double e = double(t.split_points[d * stride + s]) - double(t.split_groups[d * gstride + g]);
        squared += e * e;
      }
      radius = std::max(radius, std::sqrt(squared));
    }
    t.split_groups[3 * gstride + g] =
        std::nextafter(static_cast<float>(radius * (1 + 1e-6)), std::numeric_limits<float>::max());
  }
}

BankProjections project_on_rotation_bank(const ParticleTemplate& t) {
  BankProjections b;
  const std::size_t n = t.size();
  if (t.split_words != 1) return b;  // no split points, or more than 64 (those are grouped)
  b.row = projection_row(n);
  b.values.reset(new (std::align_val_t{64}) float[kRotationBankSize * 3 * b.row]);
  for (std::size_t slot = 0; slot < kRotationBankSize; ++slot) {
    const Eigen::Matrix3d& R = banked_rotation(slot);
    float* out = b.values.get() + slot * 3 * b.row;
    for (int d = 0; d < 3; ++d)
      for (std::size_t s = 0; s < b.row; ++s)  // split_points' order: the template's (ungrouped)
        out[d * b.row + s] = static_cast<float>(kSplitScale * R.row(d).dot(t.points[std::min(s, n - 1)]));
  }
  return b;
}

namespace {

/// Per split axis, the bit masks "above the plane" over the template's words, and one
/// mask of the points too near a plane; masks hold split_words words.
struct SplitMasks {
  std::uint64_t above[3][kMaxSplitWords];
  std::uint64_t near = 0;  ///< or of all words: any point too near a plane
};

/// The points of word w (of `words`) that a template of n points holds (the rest is padding).
std::uint64_t valid_bits(std::size_t n, std::size_t words, std::size_t w) {
  return w + 1 == words && n % 64 ? (std::uint64_t(1) << (n % 64)) - 1 : ~std::uint64_t(0);
}

/// counts[] from the masks (split axes in increasing order in m.above).
void counts_from_masks(const ParticleTemplate& t, const SplitMasks& m, unsigned split, std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  for (std::size_t w = 0; w < t.split_words; ++w) {
    const std::uint64_t valid = valid_bits(t.size(), t.split_words, w);
    // side[d][b]: the points of this word on side b of axis d (all below for an axis not split).
    std::uint64_t side[3][2];
    int a = 0;
    for (int d = 0; d < 3; ++d) {
      const std::uint64_t above = (split >> d) & 1u ? m.above[a++][w] & valid : 0;
      side[d][0] = valid & ~above;
      side[d][1] = above;
    }
    for (int o = 0; o < 8; ++o)
      counts[o] += std::popcount(side[0][o & 1] & side[1][(o >> 1) & 1] & side[2][(o >> 2) & 1]);
  }
}

/// The straightforward float comparisons, point by point: the path of CPUs without AVX2
/// and the check of the vector path. distance(d, s): point s's R_d . q, scaled.
template <class Distance>
bool count_portable(const ParticleTemplate& t, const Distance& distance, const float tau[3], unsigned split,
                    std::int32_t counts[8]) {
  const float scale = static_cast<float>(kSplitScale), guard = 0.5f;  // the points are scaled
  SplitMasks m;
  int a = 0;
  for (int d = 0; d < 3; ++d) {
    if (!((split >> d) & 1u)) continue;
    for (std::size_t w = 0; w < t.split_words; ++w) m.above[a][w] = 0;
    for (std::size_t s = 0; s < t.size(); ++s) {
      const float dot = distance(d, s);
      m.above[a][s / 64] |= std::uint64_t(dot >= scale * tau[d]) << (s % 64);
      m.near |= std::uint64_t(std::fabs(dot - scale * tau[d]) < guard) << (s % 64);
    }
    ++a;
  }
  if (m.near) return false;
  counts_from_masks(t, m, split, counts);
  return true;
}

/// count_portable from R as float rows.
template <unsigned kSplit>
bool count_portable_split(const ParticleTemplate& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  const std::size_t stride = t.split_words * 64;
  const float* x = t.split_points.data();
  return count_portable(
      t,
      [&](int d, std::size_t s) {
        const float* r = rows + 3 * d;
        return r[0] * x[s] + r[1] * x[stride + s] + r[2] * x[2 * stride + s];
      },
      tau, kSplit, counts);
}

/// count_portable from the slot's projections (BankProjections::of_slot).
template <unsigned kSplit>
bool count_projected_portable_split(const ParticleTemplate& t, const float* projections, const float tau[3],
                                    std::int32_t counts[8]) {
  const std::size_t row = projection_row(t.size());
  return count_portable(
      t, [&](int d, std::size_t s) { return projections[d * row + s]; }, tau, kSplit, counts);
}

/// No split axis: one octant holds every point.
bool count_unsplit(const ParticleTemplate& t, const float*, const float*, std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  counts[0] = static_cast<std::int32_t>(t.size());
  return true;
}

/// A batch by calls of one particle's code (inlined where it is visible).
template <auto kCount>
void count_batch(const ParticleTemplate& t, const OctantQuery* queries, std::size_t n, std::int32_t* counts,
                 std::uint8_t* decided) {
  for (std::size_t k = 0; k < n; ++k) decided[k] = kCount(t, queries[k].rotation, queries[k].tau, counts + 8 * k);
}

/// Octant counts from P[S], the points above every plane of axis set S (P[0] = all
/// points, P[S] = 0 for a set with an axis not split): per split axis d, taking the points
/// above d out of each set without d leaves, after every split axis, the points above
/// exactly the planes of each set (inclusion and exclusion). Compile-time sets: it unrolls
/// into a few subtractions.
template <unsigned kSplit>
[[gnu::always_inline]] inline void counts_from_above(std::int32_t P[8], std::int32_t counts[8]) {
#pragma GCC unroll 3
  for (unsigned d = 0; d < 3; ++d) {
    if (!((kSplit >> d) & 1u)) continue;
#pragma GCC unroll 8
    for (unsigned S = 0; S < 8; ++S)
      if ((S >> d) & 1u && (S & ~kSplit) == 0) P[S ^ (1u << d)] -= P[S];
  }
#pragma GCC unroll 8
  for (unsigned o = 0; o < 8; ++o) counts[o] = P[o];
}

#ifdef VFE_OCTANT_AVX2
/// What the vector bodies read of a template, as values: a batch takes them once. (Read
/// from the template in the loop they would be loaded again for every particle, since the
/// batch's store of each decision, through a uint8_t*, could alias them.)
struct SplitView {
  const float* points;  ///< split_points
  const float* groups;  ///< split_groups
  std::size_t n, words;
};
SplitView split_view(const ParticleTemplate& t) {
  return {t.split_points.data(), t.split_groups.data(), t.size(), t.split_words};
}

/// The axes of split set kSplit in increasing order: axis[0] to axis[count - 1].
template <unsigned kSplit>
struct SplitAxes {
  static constexpr int count = std::popcount(kSplit);
  static constexpr unsigned rest = kSplit & (kSplit - 1);
  static constexpr int axis[3] = {std::countr_zero(kSplit), std::countr_zero(rest), std::countr_zero(rest & (rest - 1))};
};

/// Adds to P[S], for each set S of split axes, the points of one word above every plane of
/// S: above[a * stride] the word's mask of split axis a (in increasing axis order), valid
/// the word's points.
template <unsigned kSplit>
[[gnu::always_inline]] inline __attribute__((target("popcnt"))) void add_points_above(std::int32_t P[8],
                                                                                    const std::uint64_t* above,
                                                                                    std::size_t stride,
                                                                                    std::uint64_t valid) {
  constexpr int kAxes = SplitAxes<kSplit>::count;
  constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
#pragma GCC unroll 8
  for (unsigned S = 1; S < 8; ++S) {
    if (S & ~kSplit) continue;
    std::uint64_t all = valid;
#pragma GCC unroll 3
    for (int a = 0; a < kAxes; ++a)
      if ((S >> axis[a]) & 1u) all &= above[a * stride];
    P[S] += static_cast<std::int32_t>(_mm_popcnt_u64(all));
  }
}

/// Entry m (1 to 64): the mask of the first m points of a word in count_avx2_body's
/// interleaved order (bit 32 h + 16 l + 4 g + i holds point 32 h + 8 g + 4 l + i).
constexpr auto kInterleavedValid = [] {
  std::array<std::uint64_t, 65> m{};
  for (unsigned count = 1; count <= 64; ++count)
    for (unsigned p = 0; p < count; ++p) {
      const unsigned h = p / 32, g = (p % 32) / 8, l = (p % 8) / 4, i = p % 4;
      m[count] |= std::uint64_t(1) << (32 * h + 16 * l + 4 * g + i);
    }
  return m;
}();

/// R_d . q - tau_d, scaled, of the eight points q from s on (x, y, z: the scaled
/// coordinates): r0, r1, r2 the row R_d and shift -kSplitScale tau_d, broadcast.
[[gnu::always_inline]] inline __attribute__((target("avx2,fma"))) __m256 plane_offsets(
    __m256 r0, __m256 r1, __m256 r2, __m256 shift, const float* x, const float* y, const float* z, std::size_t s) {
  const __m256 xy = _mm256_fmadd_ps(r1, _mm256_loadu_ps(y + s), _mm256_fmadd_ps(r0, _mm256_loadu_ps(x + s), shift));
  return _mm256_fmadd_ps(r2, _mm256_loadu_ps(z + s), xy);
}

/// 32 points' rounded scaled distances (four groups of eight) packed with saturation, which
/// keeps sign and zero, into 32 bytes: their points above the plane as one movemask (in
/// the packs' interleaved order), and near gathers the bytes of those in the guard band.
[[gnu::always_inline]] inline __attribute__((target("avx2"))) std::uint32_t points_above(const __m256i k[4],
                                                                                       __m256i& near) {
  const __m256i bytes = _mm256_packs_epi16(_mm256_packs_epi32(k[0], k[1]), _mm256_packs_epi32(k[2], k[3]));
  near = _mm256_or_si256(near, _mm256_cmpeq_epi8(bytes, _mm256_setzero_si256()));
  return ~static_cast<std::uint32_t>(_mm256_movemask_epi8(bytes));
}

/// Per split axis d the scaled distance k = round(kSplitScale (R_d . q - tau_d)) of each
/// point as an integer (the points are stored scaled): k = 0 is a point within the guard
/// band (the particle goes to double), k > 0 above, k < 0 below; points_above packs 32 of
/// them into one movemask. The packs interleave the points in a fixed order, the same for
/// every axis, and a count of "above on every axis of a set" does not depend on the order
/// (kInterleavedValid masks the padding in that order).
/// kGroups: the template's groups of eight points, 1 to 8 (at most 64 points: the loops
/// unroll into straight code; larger templates take count_plain_body or count_grouped_body).
/// distance(a, s): the scaled distances R_d . q - tau_d of the eight points from s on to the
/// plane of the a-th split axis d (RotatedDistances or ProjectedDistances).
template <unsigned kSplit, std::size_t kGroups, class Distance>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_by_distances(
    std::size_t n, const Distance& distance, std::int32_t counts[8]) {
  static_assert(kGroups >= 1 && kGroups <= 8);
  constexpr int kAxes = SplitAxes<kSplit>::count;
  const __m256i below_all = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::min());
  __m256i near = _mm256_setzero_si256();
  std::int32_t P[8] = {};
  P[0] = static_cast<std::int32_t>(n);
  std::uint64_t above[kAxes] = {};
#pragma GCC unroll 2
  for (std::size_t half = 0; half < 2; ++half) {
    const std::size_t group = 4 * half;  // the half's first group
    if (group >= kGroups) break;
    // Axis by axis (the points are memory operands, reloaded from L1), so three split axes
    // fit the sixteen vector registers.
#pragma GCC unroll 3
    for (int a = 0; a < kAxes; ++a) {
      __m256i k[4];
#pragma GCC unroll 4
      for (std::size_t g = 0; g < 4; ++g)
        k[g] = group + g < kGroups ? _mm256_cvtps_epi32(distance(a, 8 * (group + g)))
                                   : below_all;  // beyond the template: below every plane, no work
      above[a] |= std::uint64_t(points_above(k, near)) << (32 * half);
    }
  }
  add_points_above<kSplit>(P, above, 1, kInterleavedValid[n]);
  if (!_mm256_testz_si256(near, near)) return false;
  counts_from_above<kSplit>(P, counts);
  return true;
}

/// Distances from the rotation: per split axis its row and shift broadcast, three products
/// per point.
template <unsigned kSplit>
struct RotatedDistances {
  static constexpr int kAxes = SplitAxes<kSplit>::count;
  __m256 r0[kAxes], r1[kAxes], r2[kAxes], shift[kAxes];
  const float *x, *y, *z;
  [[gnu::always_inline]] inline __attribute__((target("avx2,fma"))) RotatedDistances(const float* points,
                                                                                    const float* rows,
                                                                                    const float tau[3])
      : x(points), y(points + 64), z(points + 128) {
    constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
#pragma GCC unroll 3
    for (int a = 0; a < kAxes; ++a) {
      const float* r = rows + 3 * axis[a];
      r0[a] = _mm256_set1_ps(r[0]), r1[a] = _mm256_set1_ps(r[1]), r2[a] = _mm256_set1_ps(r[2]);
      shift[a] = _mm256_set1_ps(tau[axis[a]] * -static_cast<float>(kSplitScale));
    }
  }
  [[gnu::always_inline]] inline __attribute__((target("avx2,fma"))) __m256 operator()(int a, std::size_t s) const {
    return plane_offsets(r0[a], r1[a], r2[a], shift[a], x, y, z, s);
  }
};

/// Distances from the particle's slot of BankProjections: a load and an add per point.
template <unsigned kSplit, std::size_t kGroups>
struct ProjectedDistances {
  static constexpr int kAxes = SplitAxes<kSplit>::count;
  const float* row[kAxes];
  __m256 shift[kAxes];
  [[gnu::always_inline]] inline __attribute__((target("avx2"))) ProjectedDistances(const float* projections,
                                                                                  const float tau[3]) {
    constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
#pragma GCC unroll 3
    for (int a = 0; a < kAxes; ++a) {
      row[a] = projections + axis[a] * projection_row(8 * kGroups);
      shift[a] = _mm256_set1_ps(tau[axis[a]] * -static_cast<float>(kSplitScale));
    }
  }
  [[gnu::always_inline]] inline __attribute__((target("avx2"))) __m256 operator()(int a, std::size_t s) const {
    return _mm256_add_ps(_mm256_loadu_ps(row[a] + s), shift[a]);
  }
};

/// The count of a template of at most 64 points (one word: split_points' stride is 64).
template <unsigned kSplit, std::size_t kGroups>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_avx2_body(
    const SplitView& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  return count_by_distances<kSplit, kGroups>(t.n, RotatedDistances<kSplit>(t.points, rows, tau), counts);
}

/// The same from the particle's slot of BankProjections: each point's distance to a plane is
/// a load and an add instead of three products.
template <unsigned kSplit, std::size_t kGroups>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_projected_body(
    std::size_t n, const float* projections, const float tau[3], std::int32_t counts[8]) {
  return count_by_distances<kSplit, kGroups>(n, ProjectedDistances<kSplit, kGroups>(projections, tau), counts);
}

/// A batch of count_projected_body, the rows of the particle kAhead further asked for first:
/// the megabytes of projections do not stay in the core's caches, and the slots are random.
/// A row starts on a 32-byte boundary and holds whole 32-byte groups, so steps of a line
/// from its start reach every line it spans.
template <unsigned kSplit, std::size_t kGroups>
__attribute__((target("avx2,fma,popcnt"))) void count_projected_batch_avx2(const ParticleTemplate& t,
                                                                         const OctantQuery* queries, std::size_t n,
                                                                         std::int32_t* counts, std::uint8_t* decided) {
  constexpr std::size_t kAhead = 8, kRowBytes = 4 * projection_row(8 * kGroups);
  constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
  const std::size_t points = t.size();
  for (std::size_t k = 0; k < n; ++k) {
    if (k + kAhead < n) {
      const char* ahead = reinterpret_cast<const char*>(queries[k + kAhead].rotation);
#pragma GCC unroll 3
      for (int a = 0; a < SplitAxes<kSplit>::count; ++a) {
        const char* row = ahead + axis[a] * kRowBytes;
#pragma GCC unroll 4
        for (std::size_t b = 0; b < kRowBytes; b += 64) __builtin_prefetch(row + b);
      }
    }
    decided[k] = count_projected_body<kSplit, kGroups>(points, queries[k].rotation, queries[k].tau, counts + 8 * k);
  }
}

/// Entry b: the 64-bit mask with byte i all ones for each bit i of b (a group's eight
/// points at once).
constexpr auto kGroupBytes = [] {
  std::array<std::uint64_t, 256> m{};
  for (unsigned b = 0; b < 256; ++b)
    for (unsigned i = 0; i < 8; ++i)
      if ((b >> i) & 1u) m[b] |= std::uint64_t(0xFF) << (8 * i);
  return m;
}();

/// Entry b: the numbers of the bits set in b, in increasing order, then zeros.
constexpr auto kCrossedGroups = [] {
  std::array<std::array<std::uint8_t, 8>, 256> m{};
  for (unsigned b = 0; b < 256; ++b) {
    unsigned k = 0;
    for (unsigned i = 0; i < 8; ++i)
      if ((b >> i) & 1u) m[b][k++] = static_cast<std::uint8_t>(i);
  }
  return m;
}();

/// count_avx2 for 65 to kMostUngroupedWords x 64 points compared one by one:
/// count_avx2_body's comparisons and packs over every word, axis after axis (four
/// broadcasts live), the last word's padding masked by kInterleavedValid. Up to about 800
/// points this costs no more than the groups' test (vfe_bench_octant_count: 1.7 times less
/// at 130 points, the same at 815, 1.4 to 1.8 times more at 2000 and 4000).
template <unsigned kSplit>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_plain_body(
    const SplitView& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  constexpr int kAxes = SplitAxes<kSplit>::count;
  constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
  const std::size_t n = t.n, words = t.words, stride = words * 64;
  const float* x = t.points;
  const float* y = x + stride;
  const float* z = y + stride;
  __m256i near = _mm256_setzero_si256();
  std::uint64_t above[kAxes][kMaxSplitWords];
  for (int a = 0; a < kAxes; ++a) {
    const float* r = rows + 3 * axis[a];
    const __m256 r0 = _mm256_set1_ps(r[0]), r1 = _mm256_set1_ps(r[1]), r2 = _mm256_set1_ps(r[2]);
    const __m256 shift = _mm256_set1_ps(tau[axis[a]] * -static_cast<float>(kSplitScale));
    for (std::size_t w = 0; w < words; ++w) {
      std::uint64_t word = 0;
#pragma GCC unroll 2
      for (std::size_t half = 0; half < 2; ++half) {
        __m256i k[4];
#pragma GCC unroll 4
        for (std::size_t g = 0; g < 4; ++g) {
          k[g] = _mm256_cvtps_epi32(plane_offsets(r0, r1, r2, shift, x, y, z, 64 * w + 32 * half + 8 * g));
        }
        word |= std::uint64_t(points_above(k, near)) << (32 * half);
      }
      above[a][w] = word;
    }
  }
  if (!_mm256_testz_si256(near, near)) return false;
  std::int32_t P[8] = {};
  P[0] = static_cast<std::int32_t>(n);
  const std::uint64_t last = kInterleavedValid[n - 64 * (words - 1)];
  for (std::size_t w = 0; w < words; ++w)
    add_points_above<kSplit>(P, &above[0][w], kMaxSplitWords, w + 1 == words ? last : ~std::uint64_t(0));
  counts_from_above<kSplit>(P, counts);
  return true;
}

/// count_avx2 for more than kMostUngroupedWords x 64 points (split_groups): per split
/// axis, the balls of eight groups at a time against the plane. A group whose ball the
/// plane misses by more than two guard bands (1 in scaled units; float's error on the
/// distance is below 0.05 there) lies on one side whole, none of its points near; only the
/// groups the plane crosses are compared point by point, as count_avx2_body does. The same
/// counts and refusals as comparing every point; at 860 points (chi = 1 takes 815), under a
/// quarter of the groups cross a plane at a random offset
/// (OctantSplit.GroupsOfALargeTemplateAreCompact).
template <unsigned kSplit>
[[gnu::always_inline]] inline __attribute__((target("avx2,fma,popcnt"))) bool count_grouped_body(
    const SplitView& t, const float* rows, const float tau[3], std::int32_t counts[8]) {
  constexpr int kAxes = SplitAxes<kSplit>::count;
  constexpr const int(&axis)[3] = SplitAxes<kSplit>::axis;
  const std::size_t n = t.n, words = t.words, stride = words * 64, gstride = words * 8;
  const std::size_t groups = (n + 7) / 8;
  const float* x = t.points;
  const float* y = x + stride;
  const float* z = y + stride;
  const float* cx = t.groups;
  const float* cy = cx + gstride;
  const float* cz = cy + gstride;
  const float* radii = cz + gstride;
  const unsigned last_groups = static_cast<unsigned>((std::uint64_t(1) << (groups - 8 * (words - 1))) - 1);
  const __m256 margin = _mm256_set1_ps(1.0f), zero = _mm256_setzero_ps();
  __m256i near = _mm256_setzero_si256();
  // Per split axis and word, its points above the plane: first the groups wholly above as
  // whole bytes, then a byte per crossed group stored over its zero byte. Each axis has its
  // own words and all are read after the last axis, when the byte stores are long done (a
  // word read right after its bytes were stored waits for them: they cannot be forwarded).
  alignas(8) std::uint8_t above[kAxes][kMaxSplitWords * 8];
  std::uint16_t crossed[kMaxSplitWords * 8 + 8];  // groups a plane crosses (8 spare: whole stores)
  for (int a = 0; a < kAxes; ++a) {
    std::size_t count = 0;
    const float* r = rows + 3 * axis[a];
    const __m256 r0 = _mm256_set1_ps(r[0]), r1 = _mm256_set1_ps(r[1]), r2 = _mm256_set1_ps(r[2]);
    const __m256 shift = _mm256_set1_ps(tau[axis[a]] * -static_cast<float>(kSplitScale));
    for (std::size_t w = 0; w < words; ++w) {
      const std::size_t g0 = 8 * w;
      const __m256 centre = plane_offsets(r0, r1, r2, shift, cx, cy, cz, g0);
      // |n . (q - c)| <= |n| |q - c|: the ball's reach along the plane's normal.
      const __m256 reach = _mm256_add_ps(_mm256_loadu_ps(radii + g0), margin);
      const unsigned valid = w + 1 == words ? last_groups : 0xFFu;
      const unsigned whole_above =
          static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(centre, reach, _CMP_GT_OQ))) & valid;
      const unsigned whole_below = static_cast<unsigned>(
          _mm256_movemask_ps(_mm256_cmp_ps(_mm256_add_ps(centre, reach), zero, _CMP_LT_OQ)));
      const unsigned cross = ~(whole_above | whole_below) & valid;
      std::memcpy(above[a] + g0, &kGroupBytes[whole_above], sizeof(std::uint64_t));
      // The crossed groups' numbers appended without a branch (a loop over the bits of each
      // word would mispredict its end in nearly every word).
      const __m128i numbers = _mm_add_epi16(_mm_cvtepu8_epi16(_mm_loadl_epi64(
                                                reinterpret_cast<const __m128i*>(kCrossedGroups[cross].data()))),
                                            _mm_set1_epi16(static_cast<short>(g0)));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(crossed + count), numbers);
      count += static_cast<std::size_t>(std::popcount(cross));
    }
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t g = crossed[i], s = 8 * g;
      const __m256i k = _mm256_cvtps_epi32(plane_offsets(r0, r1, r2, shift, x, y, z, s));
      near = _mm256_or_si256(near, _mm256_cmpeq_epi32(k, _mm256_setzero_si256()));
      above[a][g] = static_cast<std::uint8_t>(~_mm256_movemask_ps(_mm256_castsi256_ps(k)));
    }
  }
  if (!_mm256_testz_si256(near, near)) return false;
  std::int32_t P[8] = {};
  P[0] = static_cast<std::int32_t>(n);
  for (std::size_t w = 0; w < words; ++w) {
    std::uint64_t word[kAxes];
    for (int a = 0; a < kAxes; ++a) std::memcpy(&word[a], above[a] + 8 * w, sizeof word[a]);
    add_points_above<kSplit>(P, word, 1, valid_bits(n, words, w));
  }
  counts_from_above<kSplit>(P, counts);
  return true;
}

/// One particle's count by a counting body, and a batch by the same body in one loop (the
/// body is inlined into both).
template <auto kBody>
__attribute__((target("avx2,fma,popcnt"))) bool count_one_avx2(const ParticleTemplate& t, const float* rows,
                                                              const float tau[3], std::int32_t counts[8]) {
  return kBody(split_view(t), rows, tau, counts);
}

template <auto kBody>
__attribute__((target("avx2,fma,popcnt"))) void count_batch_avx2(const ParticleTemplate& t,
                                                               const OctantQuery* queries, std::size_t n,
                                                               std::int32_t* counts, std::uint8_t* decided) {
  const SplitView view = split_view(t);
  for (std::size_t k = 0; k < n; ++k) decided[k] = kBody(view, queries[k].rotation, queries[k].tau, counts + 8 * k);
}

/// The counter whose split sets 1 to 7 take these bodies (and no projected code).
template <auto... kBodies>
constexpr OctantCounter vector_counter() {
  return {{count_unsplit, count_one_avx2<kBodies>...}, {count_batch<count_unsplit>, count_batch_avx2<kBodies>...}, {}};
}

/// Templates of kGroups groups of eight points (at most 64), with their projected code.
template <std::size_t kGroups, unsigned... kSplits>
constexpr OctantCounter sized_counter_of(std::integer_sequence<unsigned, kSplits...>) {
  OctantCounter c = vector_counter<count_avx2_body<kSplits + 1, kGroups>...>();
  const OctantBatchFn projected[8] = {count_batch<count_unsplit>, count_projected_batch_avx2<kSplits + 1, kGroups>...};
  for (int split = 0; split < 8; ++split) c.projected_batch_by_split[split] = projected[split];
  return c;
}
template <std::size_t kGroups>
constexpr OctantCounter sized_counter() {
  return sized_counter_of<kGroups>(std::make_integer_sequence<unsigned, 7>{});
}

bool has_avx2() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }
#endif

}  // namespace

const OctantCounter& octant_counter(const ParticleTemplate& t, SplitPath path) {
  static const OctantCounter portable{
      {count_unsplit, count_portable_split<1>, count_portable_split<2>, count_portable_split<3>,
       count_portable_split<4>, count_portable_split<5>, count_portable_split<6>, count_portable_split<7>},
      {count_batch<count_unsplit>, count_batch<count_portable_split<1>>, count_batch<count_portable_split<2>>,
       count_batch<count_portable_split<3>>, count_batch<count_portable_split<4>>,
       count_batch<count_portable_split<5>>, count_batch<count_portable_split<6>>,
       count_batch<count_portable_split<7>>},
      {count_batch<count_unsplit>, count_batch<count_projected_portable_split<1>>,
       count_batch<count_projected_portable_split<2>>, count_batch<count_projected_portable_split<3>>,
       count_batch<count_projected_portable_split<4>>, count_batch<count_projected_portable_split<5>>,
       count_batch<count_projected_portable_split<6>>, count_batch<count_projected_portable_split<7>>}};
#ifdef VFE_OCTANT_AVX2
  // Entry g: templates of g groups of eight points (at most 64 points).
  static const OctantCounter by_groups[9] = {{},
                                             sized_counter<1>(),
                                             sized_counter<2>(),
                                             sized_counter<3>(),
                                             sized_counter<4>(),
                                             sized_counter<5>(),
                                             sized_counter<6>(),
                                             sized_counter<7>(),
                                             sized_counter<8>()};
  static const OctantCounter plain =
      vector_counter<count_plain_body<1>, count_plain_body<2>, count_plain_body<3>, count_plain_body<4>,
                     count_plain_body<5>, count_plain_body<6>, count_plain_body<7>>();
  static const OctantCounter grouped =
      vector_counter<count_grouped_body<1>, count_grouped_body<2>, count_grouped_body<3>, count_grouped_body<4>,
                     count_grouped_body<5>, count_grouped_body<6>, count_grouped_body<7>>();
  static const bool avx2 = has_avx2();
  if (path == SplitPath::fastest && avx2) {
    if (t.split_words == 1) return by_groups[(t.size() + 7) / 8];
    return t.split_words <= kMostUngroupedWords ? plain : grouped;
  }
#endif
  (void)t, (void)path;
  return portable;
}

bool count_octants(const ParticleTemplate& t, const Eigen::Matrix3d& R, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  float rows[9];
  rotation_rows(R, rows);
  return count_octants(t, rows, split, tau, counts, path);
}

bool count_octants(const ParticleTemplate& t, const float* rows, unsigned split, const double tau[3],
                   std::int32_t counts[8], SplitPath path) {
  const float taus[3] = {static_cast<float>(tau[0]), static_cast<float>(tau[1]), static_cast<float>(tau[2])};
  return octant_counter(t, path).by_split[split & 7u](t, rows, taus, counts);
}

}  // namespace vfe::kernels

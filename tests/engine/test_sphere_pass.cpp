// The sphere pass (engine/src/sphere_pass.hpp) against a one-particle-at-a-time oracle
// written from its contract: the validation's sums in particle order, the first bad
// particle, the spheres beyond the box, floor((x - origin) / h) per axis for the cell and
// the centres outside left to the caller. Both builds (baseline x86-64 and the fastest the
// CPU has) must give the oracle's results bit for bit, on packed and strided arrays, every
// chunk length (the four-lane steps and the tail), faces, bad values and outside centres.
#include "sphere_pass.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

namespace vfe::test {
namespace {

using detail::CentreGrid;
using detail::ParticleArrays;
using detail::PassBuild;
using detail::SphereBounds;
using detail::Validation;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Spheres in an array of records of `stride` doubles (x, y, z, r first): stride 4 is not
/// packed; packed() gives the separate 3n and n arrays the fast loads take.
struct Spheres {
  std::vector<double> records;
  int stride = 4;
  std::vector<double> centres, radii;  // packed copies
  std::int64_t n() const { return static_cast<std::int64_t>(records.size()) / stride; }
  void add(double x, double y, double z, double r) {
    records.insert(records.end(), {x, y, z, r});
    records.resize(records.size() + static_cast<std::size_t>(stride - 4), -7.0);
  }
  ParticleArrays arrays(bool packed) {
    ParticleArrays pa;
    pa.n = n();
    if (packed) {
      centres.clear();
      radii.clear();
      for (std::int64_t p = 0; p < n(); ++p) {
        centres.insert(centres.end(), {record(p)[0], record(p)[1], record(p)[2]});
        radii.push_back(record(p)[3]);
      }
      pa.centres = reinterpret_cast<const char*>(centres.data());
      pa.radii = reinterpret_cast<const char*>(radii.data());
      return pa;
    }
    pa.centres = reinterpret_cast<const char*>(records.data());
    pa.radii = reinterpret_cast<const char*>(records.data() + 3);
    pa.centres_stride = pa.radii_stride = stride * static_cast<std::int64_t>(sizeof(double));
    return pa;
  }
  double* record(std::int64_t p) { return records.data() + p * stride; }
};

/// The grid of the cases: 7 x 5 x 6 cells of 0.5 x 0.25 x 1 from (-1, 2, 0.5).
struct Grid {
  double origin[3] = {-1.0, 2.0, 0.5}, spacing[3] = {0.5, 0.25, 1.0};
  std::int64_t cells[3] = {7, 5, 6};
  std::int64_t count() const { return cells[0] * cells[1] * cells[2]; }
  CentreGrid centre_grid(double* field) const {
    CentreGrid g{};
    for (int d = 0; d < 3; ++d) {
      g.origin[d] = origin[d];
      g.inv_spacing[d] = 1.0 / spacing[d];
      g.cells[d] = double(cells[d]);
    }
    g.strides[0] = static_cast<std::int32_t>(cells[0]);
    g.strides[1] = static_cast<std::int32_t>(cells[0] * cells[1]);
    g.field = field;
    return g;
  }
  /// The box of the validation's beyond count: the grid widened by 0.1.
  SphereBounds bounds() const {
    SphereBounds b;
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = origin[d] - 0.1;
      b.hi[d] = origin[d] + double(cells[d]) * spacing[d] + 0.1;
    }
    return b;
  }
};

struct Outcome {
  Validation v;
  bool good = true;
  std::vector<double> field;
  std::vector<std::int64_t> left;
};

/// The contract, one particle at a time.
Outcome oracle(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const Grid& grid, Validation start) {
  Outcome o{start, true, std::vector<double>(static_cast<std::size_t>(grid.count()), 0.0), {}};
  const SphereBounds b = grid.bounds();
  for (std::int64_t p = first; p < first + count; ++p) {
    const Eigen::Vector3d c = pa.centre(p);
    const double r = pa.radius(p);
    const double v = 4.0 / 3.0 * std::numbers::pi * r * r * r;
    const bool ok = c.allFinite() && std::isfinite(r) && r > 0 && v >= std::numeric_limits<double>::min() &&
                    v < 1e300 && std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2]) + r < 1e300;
    if (!ok) {
      o.good = false;
      o.v.first_bad = std::min(o.v.first_bad, p);
      continue;
    }
    o.v.volume += v;
    o.v.d_min = std::min(o.v.d_min, 2 * r);
    o.v.d_max = std::max(o.v.d_max, 2 * r);
    bool beyond = false;
    for (int d = 0; d < 3; ++d) beyond = beyond || c[d] - r < b.lo[d] || c[d] + r > b.hi[d];
    o.v.beyond += beyond;
    std::int64_t cell = 0, stride = 1;
    bool inside = true;
    for (int d = 0; d < 3; ++d) {
      const double t = std::floor((c[d] - grid.origin[d]) * (1.0 / grid.spacing[d]));
      inside = inside && t >= 0 && t < double(grid.cells[d]);
      if (inside) cell += static_cast<std::int64_t>(t) * stride;
      stride *= grid.cells[d];
    }
    if (inside)
      o.field[static_cast<std::size_t>(cell)] += v;
    else
      o.left.push_back(p);
  }
  if (!o.good) o.left.clear();  // a bad chunk leaves nothing: the compute fails
  return o;
}

Outcome run_pass(const ParticleArrays& pa, std::int64_t first, std::int64_t count, const Grid& grid, Validation start,
                 PassBuild build, bool deposit) {
  Outcome o{start, true, std::vector<double>(static_cast<std::size_t>(grid.count()), 0.0), {}};
  if (!deposit) {
    o.good = detail::check_sphere_chunk(pa, first, count, grid.bounds(), o.v, build);
    return o;
  }
  std::int64_t left[detail::kSphereChunk];
  const CentreGrid g = grid.centre_grid(o.field.data());
  const std::int64_t nleft = detail::deposit_sphere_chunk(pa, first, count, grid.bounds(), g, o.v, left, build);
  o.left.assign(left, left + nleft);
  o.good = o.v.first_bad == start.first_bad;
  return o;
}

void expect_same(const Outcome& got, const Outcome& want, bool deposit, const std::string& what) {
  SCOPED_TRACE(what);
  EXPECT_EQ(got.v.first_bad, want.v.first_bad);
  if (!want.good) return;  // a failed chunk promises first_bad only
  EXPECT_EQ(got.v.volume, want.v.volume);  // the same sum in the same order: bit for bit
  EXPECT_EQ(got.v.d_min, want.v.d_min);
  EXPECT_EQ(got.v.d_max, want.v.d_max);
  EXPECT_EQ(got.v.beyond, want.v.beyond);
  if (!deposit) return;
  EXPECT_EQ(got.left, want.left);
  for (std::size_t c = 0; c < want.field.size(); ++c) ASSERT_EQ(got.field[c], want.field[c]) << "cell " << c;
}

/// Spheres around the grid: most inside, some beyond it, some exactly on cell faces and
/// just below the lower ones (where truncation toward zero would differ from floor).
Spheres scene(std::uint32_t seed, int n, int stride) {
  const Grid grid;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.15, 1.15), rad(0.01, 0.2);
  std::uniform_int_distribution<int> kind(0, 9);
  Spheres s;
  s.stride = stride;
  for (int i = 0; i < n; ++i) {
    double c[3];
    for (int d = 0; d < 3; ++d) {
      const double length = double(grid.cells[d]) * grid.spacing[d];
      c[d] = grid.origin[d] + u(rng) * length;
      const int k = kind(rng);
      const double face = grid.origin[d] + double(std::uniform_int_distribution<int>(0, int(grid.cells[d]))(rng)) *
                                               grid.spacing[d];
      if (k == 0) c[d] = face;                                  // on a face (or the upper boundary)
      if (k == 1) c[d] = std::nextafter(face, -kInf);           // just below one
      if (k == 2) c[d] = std::nextafter(grid.origin[d], -kInf);  // just below the grid
    }
    s.add(c[0], c[1], c[2], rad(rng));
  }
  return s;
}

TEST(SpherePass, BothBuildsEqualTheOracleOnEveryChunkLength) {
  for (const int stride : {4, 6})
    for (const bool packed : {true, false})
      for (const bool deposit : {true, false}) {
        Spheres s = scene(31, 600, stride);
        const ParticleArrays pa = s.arrays(packed);
        const Grid grid;
        for (std::int64_t count = 1; count <= detail::kSphereChunk; count += count < 12 ? 1 : 61)
          for (const std::int64_t first : {std::int64_t(0), std::int64_t(3), std::int64_t(600) - count}) {
            Validation start;  // a running validation, as across the chunks of a range
            start.volume = 0.125;
            start.d_min = 0.3;
            start.beyond = 2;
            const Outcome want = oracle(pa, first, count, grid, start);
            ASSERT_TRUE(want.good);
            const std::string what = "stride " + std::to_string(stride) + (packed ? " packed" : " strided") +
                                     (deposit ? " deposit" : " check") + ", particles " + std::to_string(first) +
                                     " + " + std::to_string(count);
            expect_same(run_pass(pa, first, count, grid, start, PassBuild::fastest, deposit), want, deposit,
                        what + ", fastest");
            expect_same(run_pass(pa, first, count, grid, start, PassBuild::baseline, deposit), want, deposit,
                        what + ", baseline");
          }
      }
}

TEST(SpherePass, ScenesHaveCellsLeftAndSpheresBeyond) {  // the cases above exercise every branch
  Spheres s = scene(31, 600, 4);
  const ParticleArrays pa = s.arrays(true);
  const Outcome o = oracle(pa, 0, 256, Grid{}, Validation{});
  EXPECT_GT(o.left.size(), 20u);
  EXPECT_GT(o.v.beyond, 20);
  EXPECT_LT(o.v.beyond, 256);
}

TEST(SpherePass, NamesTheFirstBadParticleOfAChunk) {
  struct Bad {
    const char* name;
    int field;  // 0..2: a centre coordinate, 3: the radius
    double value;
  };
  const Bad bads[] = {{"NaN radius", 3, kNaN},
                      {"negative radius", 3, -0.1},
                      {"zero radius", 3, 0.0},
                      {"negative zero radius", 3, -0.0},
                      {"infinite radius", 3, kInf},
                      {"volume below the smallest normal", 3, 1e-103},
                      {"volume beyond 1e300", 3, 1e100},
                      {"NaN centre", 1, kNaN},
                      {"infinite centre", 2, -kInf},
                      {"centre beyond 1e300", 0, 2e300}};
  const std::int64_t count = 203;  // 50 four-lane steps and a tail of 3
  for (const Bad& bad : bads)
    for (const std::int64_t at : {std::int64_t(0), std::int64_t(97), std::int64_t(201), count - 1})
      for (const bool packed : {true, false})
        for (const bool deposit : {true, false}) {
          Spheres s = scene(32, int(count), 4);
          s.record(at)[bad.field] = bad.value;
          if (at + 5 < count) s.record(at + 5)[3] = kNaN;  // a second bad particle: the first is named
          const ParticleArrays pa = s.arrays(packed);
          const Outcome want = oracle(pa, 0, count, Grid{}, Validation{});
          ASSERT_FALSE(want.good) << bad.name;
          ASSERT_EQ(want.v.first_bad, at);
          const std::string what = std::string(bad.name) + " at " + std::to_string(at) + (packed ? " packed" : "");
          for (const PassBuild build : {PassBuild::fastest, PassBuild::baseline}) {
            const Outcome got = run_pass(pa, 0, count, Grid{}, Validation{}, build, deposit);
            EXPECT_FALSE(got.good) << what;
            expect_same(got, want, deposit, what);
          }
        }
}

}  // namespace
}  // namespace vfe::test

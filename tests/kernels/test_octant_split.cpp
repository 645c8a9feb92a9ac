// Counting sub-elements per octant against the straightforward count in double: every
// count the float path returns must be exact, including points placed within 1e-12 or
// 1e-6 of a split plane (those must be refused, never miscounted) and 2e-5 from it (those
// float decides).
#include <vfe/kernels/octant_split.hpp>

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <random>
#include <vector>

namespace {

using vfe::kernels::ParticleTemplate;

/// Brute force: point q is above axis d's plane when R.row(d) . q >= tau[d] (double).
void brute_counts(const ParticleTemplate& t, const Eigen::Matrix3d& R, unsigned split, const double tau[3],
                  std::int32_t counts[8]) {
  for (int o = 0; o < 8; ++o) counts[o] = 0;
  for (const Eigen::Vector3d& q : t.points) {
    int o = 0;
    for (int d = 0; d < 3; ++d)
      if ((split >> d) & 1u && R.row(d).dot(q) >= tau[d]) o |= 1 << d;
    ++counts[o];
  }
}

class OctantSplitPaths : public ::testing::TestWithParam<vfe::kernels::SplitPath> {};

TEST_P(OctantSplitPaths, CountsEqualTheStraightforwardCountOnMillionsOfSubElements) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::int64_t sub_elements = 0, refused = 0, cases = 0, near_cases = 0, clear_cases = 0, clear_refused = 0;
  // Every count of eight-point groups up to 64 points (each has its own code), then 65 to 512
  // points (compared one by one; 512 and 513 either side of the rule) and groups.
  for (const int n : {1, 7, 12, 20, 29, 35, 45, 53, 64, 65, 130, 300, 512, 513, 815}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    ASSERT_EQ(t.split_words, (t.size() + 63) / 64);
    for (int c = 0; c < 4000; ++c) {
      const Eigen::Matrix3d R = vfe::kernels::random_rotation(std::uint64_t(c), std::uint64_t(n));
      const unsigned split = 1 + static_cast<unsigned>(c % 7);
      double tau[3];
      for (int d = 0; d < 3; ++d) tau[d] = 0.9 * u(rng);
      // One case in four puts a point within 1e-12 of the first split plane, one in eight
      // within 1e-6 (inside the guard band: refused too), one in eight 2e-5 from it
      // (outside the band: float decides, and must decide right).
      const bool near = c % 4 == 0, mid = c % 8 == 1, clear = c % 8 == 5;
      const int d = std::countr_zero(split);
      const Eigen::Vector3d& q = t.points[static_cast<std::size_t>(c) % t.size()];
      const double side = c % 16 < 8 ? 1.0 : -1.0;
      if (near) tau[d] = R.row(d).dot(q) + side * 1e-12;
      if (mid) tau[d] = R.row(d).dot(q) + side * 1e-6;
      if (clear) tau[d] = R.row(d).dot(q) + side * 2e-5;
      std::int32_t got[8], want[8];
      brute_counts(t, R, split, tau, want);
      ++cases;
      near_cases += near || mid;
      clear_cases += clear;
      if (!vfe::kernels::count_octants(t, R, split, tau, got, GetParam())) {
        ++refused;
        clear_refused += clear;
        continue;
      }
      EXPECT_FALSE(near || mid) << "n = " << n << ", case " << c << ": a point in the guard band was not refused";
      for (int o = 0; o < 8; ++o) ASSERT_EQ(got[o], want[o]) << "n = " << n << ", case " << c << ", octant " << o;
      sub_elements += n;
    }
  }
  EXPECT_GT(sub_elements, 2000000);
  // Only the near cases and a few random ones go to double.
  EXPECT_LT(refused, near_cases + cases / 50) << refused << " of " << cases;
  EXPECT_LT(clear_refused, clear_cases / 50) << "points 2e-5 from a plane sent to double";
}

// The lanes that pad a template to groups of eight are no points of it: planes through the
// template's centre (where zero padding would lie in every guard band) are refused only
// for a real point near one of them.
TEST_P(OctantSplitPaths, PaddingNeverRefusesAParticle) {
  std::int64_t decided = 0;
  for (const int n : {1, 7, 12, 20, 29, 35, 45, 53, 65, 130, 300, 513, 815}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    for (int c = 0; c < 700; ++c) {
      const Eigen::Matrix3d R = vfe::kernels::random_rotation(std::uint64_t(c), std::uint64_t(n) + 100);
      const unsigned split = 1 + static_cast<unsigned>(c % 7);
      const double tau[3] = {0, 0, 0};
      double nearest = 1;
      for (const Eigen::Vector3d& q : t.points)
        for (int d = 0; d < 3; ++d)
          if ((split >> d) & 1u) nearest = std::min(nearest, std::abs(R.row(d).dot(q)));
      std::int32_t got[8], want[8];
      if (!vfe::kernels::count_octants(t, R, split, tau, got, GetParam())) {
        EXPECT_LT(nearest, 1e-5) << "n = " << n << ", case " << c << ": refused with every point " << nearest
                                 << " from the planes";
        continue;
      }
      brute_counts(t, R, split, tau, want);
      for (int o = 0; o < 8; ++o) ASSERT_EQ(got[o], want[o]) << "n = " << n << ", case " << c << ", octant " << o;
      ++decided;
    }
  }
  EXPECT_GT(decided, 12 * 690);  // n = 1's one point is the centre, on every plane: always refused
}

// A batch of one split set gives what one call per particle gives, refusals included.
TEST_P(OctantSplitPaths, ABatchEqualsOneCallPerParticle) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int refused = 0, decided = 0;
  for (const int n : {7, 35, 64, 130, 815}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    const vfe::kernels::OctantCounter& counter = vfe::kernels::octant_counter(t, GetParam());
    for (unsigned split = 0; split < 8; ++split) {
      constexpr std::size_t kBatch = 40;
      std::vector<std::array<float, 9>> rows(kBatch);
      std::vector<vfe::kernels::OctantQuery> queries(kBatch);
      for (std::size_t k = 0; k < kBatch; ++k) {
        const Eigen::Matrix3d R = vfe::kernels::random_rotation(k, split);
        vfe::kernels::rotation_rows(R, rows[k].data());
        queries[k].rotation = rows[k].data();
        for (int d = 0; d < 3; ++d) queries[k].tau[d] = static_cast<float>(0.9 * u(rng));
        // Every third particle has a point on its first split plane: refused.
        if (split && k % 3 == 0) {
          const int d = std::countr_zero(split);
          queries[k].tau[d] = static_cast<float>(R.row(d).dot(t.points[k % t.size()]));
        }
      }
      std::vector<std::int32_t> counts(8 * kBatch, -1);
      std::vector<std::uint8_t> ok(kBatch, 2);
      counter.batch_by_split[split](t, queries.data(), kBatch, counts.data(), ok.data());
      for (std::size_t k = 0; k < kBatch; ++k) {
        std::int32_t one[8];
        const bool single = counter.by_split[split](t, queries[k].rotation, queries[k].tau, one);
        ASSERT_EQ(ok[k], single ? 1 : 0) << "n " << n << " split " << split << " particle " << k;
        if (!single) {
          ++refused;
          continue;
        }
        ++decided;
        for (int o = 0; o < 8; ++o) ASSERT_EQ(counts[8 * k + o], one[o]) << "n " << n << " split " << split;
      }
    }
  }
  EXPECT_GT(refused, 100);
  EXPECT_GT(decided, 500);
}

// Counts from the bank's projections against the straightforward count in double with the
// bank's own rotation: exact wherever they decide, every point within 1e-12 or 1e-6 of a
// plane refused, points 2e-5 from it decided; padding lanes (a plane through the centre)
// refuse nothing. Every template size with its own code up to 64 points, every split set.
TEST_P(OctantSplitPaths, ProjectedCountsEqualTheStraightforwardCount) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::int64_t sub_elements = 0, refused = 0, cases = 0, near_cases = 0, clear_cases = 0, clear_refused = 0;
  for (const int n : {1, 7, 8, 12, 20, 29, 35, 45, 53, 64}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    const vfe::kernels::BankProjections projections = vfe::kernels::project_on_rotation_bank(t);
    ASSERT_TRUE(projections);
    const vfe::kernels::OctantCounter& counter = vfe::kernels::octant_counter(t, GetParam());
    for (unsigned split = 1; split < 8; ++split) {
      constexpr std::size_t kBatch = 300;
      std::vector<vfe::kernels::OctantQuery> queries(kBatch);
      std::vector<std::array<double, 3>> taus(kBatch);
      std::vector<std::size_t> slots(kBatch);
      for (std::size_t k = 0; k < kBatch; ++k) {
        slots[k] = rng() % vfe::kernels::kRotationBankSize;
        const Eigen::Matrix3d& R = vfe::kernels::banked_rotation(slots[k]);
        for (int d = 0; d < 3; ++d) taus[k][d] = k % 10 == 9 ? 0.0 : 0.9 * u(rng);  // some through the centre
        const int d = std::countr_zero(split);
        const Eigen::Vector3d& q = t.points[k % t.size()];
        const double side = k % 2 ? 1.0 : -1.0;
        if (k % 4 == 0) taus[k][d] = R.row(d).dot(q) + side * 1e-12;
        if (k % 8 == 1) taus[k][d] = R.row(d).dot(q) + side * 1e-6;
        if (k % 8 == 5) taus[k][d] = R.row(d).dot(q) + side * 2e-5;
        queries[k].rotation = projections.of_slot(slots[k]);
        // The engine's thresholds are floats: the double count takes the same values.
        for (int e = 0; e < 3; ++e) {
          queries[k].tau[e] = static_cast<float>(taus[k][e]);
          taus[k][e] = double(queries[k].tau[e]);
        }
      }
      std::vector<std::int32_t> counts(8 * kBatch, -1);
      std::vector<std::uint8_t> ok(kBatch, 2);
      counter.projected_batch_by_split[split](t, queries.data(), kBatch, counts.data(), ok.data());
      for (std::size_t k = 0; k < kBatch; ++k) {
        const Eigen::Matrix3d& R = vfe::kernels::banked_rotation(slots[k]);
        double nearest = 1;
        for (const Eigen::Vector3d& q : t.points)
          for (int d = 0; d < 3; ++d)
            if ((split >> d) & 1u) nearest = std::min(nearest, std::abs(R.row(d).dot(q) - taus[k][d]));
        const bool near = nearest < 2e-6, clear = nearest > 1.5e-5;  // the guard band is 3.8e-6
        ++cases;
        near_cases += near;
        clear_cases += clear;
        ASSERT_LE(ok[k], 1);
        if (!ok[k]) {
          ++refused;
          clear_refused += clear;
          EXPECT_LT(nearest, 1e-5) << "n " << n << " split " << split << " particle " << k << ": refused with every point "
                                   << nearest << " from the planes";
          continue;
        }
        EXPECT_FALSE(near) << "n " << n << " split " << split << " particle " << k << ": a point " << nearest
                           << " from a plane was not refused";
        std::int32_t want[8];
        brute_counts(t, R, split, taus[k].data(), want);
        for (int o = 0; o < 8; ++o)
          ASSERT_EQ(counts[8 * k + o], want[o]) << "n " << n << " split " << split << " particle " << k;
        sub_elements += n;
      }
    }
  }
  EXPECT_GT(sub_elements, 300000);
  EXPECT_GT(near_cases, cases / 5);
  EXPECT_LT(refused, near_cases + cases / 50) << refused << " of " << cases;
  EXPECT_EQ(clear_refused, 0) << "points well outside the guard band sent to double";
}

// No projections for a template the count takes in words or groups (over 64 points).
TEST(OctantSplit, OnlyTemplatesOfOneWordHaveProjections) {
  ParticleTemplate t = vfe::kernels::make_fibonacci_template(65);
  vfe::kernels::prepare_octant_split(t);
  EXPECT_FALSE(vfe::kernels::project_on_rotation_bank(t));
  ParticleTemplate unequal = vfe::kernels::make_spherical_template(30);
  unequal.fractions[0] *= 2;  // unequal shares: no split points
  vfe::kernels::prepare_octant_split(unequal);
  EXPECT_FALSE(vfe::kernels::project_on_rotation_bank(unequal));
}

INSTANTIATE_TEST_SUITE_P(OctantSplit, OctantSplitPaths,
                         ::testing::Values(vfe::kernels::SplitPath::fastest, vfe::kernels::SplitPath::portable));

// The groups of a large template hold points near one another: their balls contain their
// points, and a plane through the template at a random offset and direction crosses few
// of them (in the template's own order, groups of eight would span the sphere).
TEST(OctantSplit, GroupsOfALargeTemplateAreCompact) {
  for (const int n : {600, 860}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    ASSERT_GT(t.split_words, vfe::kernels::kMostUngroupedWords) << "n " << n << " is not kept in groups";
    const std::size_t stride = t.split_words * 64, gstride = t.split_words * 8, groups = (t.size() + 7) / 8;
    ASSERT_EQ(t.split_groups.size(), 4 * gstride);
    for (std::size_t s = 0; s < t.size(); ++s) {
      double squared = 0;
      for (int d = 0; d < 3; ++d) {
        const double e = double(t.split_points[d * stride + s]) - t.split_groups[d * gstride + s / 8];
        squared += e * e;
      }
      ASSERT_LE(std::sqrt(squared), t.split_groups[3 * gstride + s / 8]) << "n " << n << " point " << s;
    }
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    double crossed = 0, tested = 0;
    for (int c = 0; c < 2000; ++c) {
      const Eigen::Vector3d normal = vfe::kernels::random_rotation(std::uint64_t(c), 5).row(0);
      const double offset = vfe::kernels::kSplitScale * t.reach * u(rng);
      for (std::size_t g = 0; g < groups; ++g) {
        double centre = -offset;
        for (int d = 0; d < 3; ++d) centre += normal[d] * t.split_groups[d * gstride + g];
        crossed += std::abs(centre) <= t.split_groups[3 * gstride + g];
        ++tested;
      }
    }
    testing::Test::RecordProperty("crossed_share_" + std::to_string(n), std::to_string(crossed / tested));
    EXPECT_LT(crossed / tested, n > 700 ? 0.25 : 0.3) << "n " << n;  // 0.226 and 0.259 when written
  }
}

TEST(OctantSplit, NoSplitPutsEveryPointInTheFirstOctant) {
  ParticleTemplate t = vfe::kernels::make_fibonacci_template(100);
  vfe::kernels::prepare_octant_split(t);
  const double tau[3] = {0, 0, 0};
  std::int32_t counts[8];
  ASSERT_TRUE(vfe::kernels::count_octants(t, Eigen::Matrix3d::Identity(), 0u, tau, counts));
  EXPECT_EQ(counts[0], 100);
  for (int o = 1; o < 8; ++o) EXPECT_EQ(counts[o], 0);
}

TEST(OctantSplit, TemplatesWithUnequalSharesOrTooManyPointsAreLeftToScattering) {
  ParticleTemplate spherical = vfe::kernels::make_spherical_template(60);
  spherical.fractions[0] *= 1.5;  // unequal shares
  vfe::kernels::prepare_octant_split(spherical);
  EXPECT_TRUE(spherical.split_points.empty());
  ParticleTemplate big = vfe::kernels::make_fibonacci_template(int(vfe::kernels::kMaxSplitWords * 64 + 1));
  vfe::kernels::prepare_octant_split(big);
  EXPECT_TRUE(big.split_points.empty());
}

}  // namespace

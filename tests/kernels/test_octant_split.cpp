// Counting sub-elements per octant against the straightforward count in double: every
// count the float path returns must be exact, including points placed within 1e-12 of a
// split plane (those must be refused, never miscounted).
#include <vfe/kernels/octant_split.hpp>

#include <gtest/gtest.h>

#include <bit>
#include <random>

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
  std::int64_t sub_elements = 0, refused = 0, cases = 0, near_cases = 0;
  for (const int n : {1, 7, 35, 45, 64, 65, 130, 815}) {
    ParticleTemplate t = vfe::kernels::make_fibonacci_template(n);
    vfe::kernels::prepare_octant_split(t);
    ASSERT_EQ(t.split_words, (t.size() + 63) / 64);
    for (int c = 0; c < 4000; ++c) {
      const Eigen::Matrix3d R = vfe::kernels::random_rotation(std::uint64_t(c), std::uint64_t(n));
      const unsigned split = 1 + static_cast<unsigned>(c % 7);
      double tau[3];
      for (int d = 0; d < 3; ++d) tau[d] = 0.9 * u(rng);
      // One case in four puts a point within 1e-12 of the first split plane.
      const bool near = c % 4 == 0;
      if (near) {
        const int d = std::countr_zero(split);
        const Eigen::Vector3d& q = t.points[static_cast<std::size_t>(c) % t.size()];
        tau[d] = R.row(d).dot(q) + (c % 8 == 0 ? 1e-12 : -1e-12);
      }
      std::int32_t got[8], want[8];
      brute_counts(t, R, split, tau, want);
      ++cases;
      near_cases += near;
      if (!vfe::kernels::count_octants(t, R, split, tau, got, GetParam())) {
        ++refused;
        continue;
      }
      EXPECT_FALSE(near) << "n = " << n << ", case " << c << ": a point 1e-12 from a plane was not refused";
      for (int o = 0; o < 8; ++o) ASSERT_EQ(got[o], want[o]) << "n = " << n << ", case " << c << ", octant " << o;
      sub_elements += n;
    }
  }
  EXPECT_GT(sub_elements, 2000000);
  // Only the near cases and a few random ones go to double.
  EXPECT_LT(refused, near_cases + cases / 50) << refused << " of " << cases;
}

INSTANTIATE_TEST_SUITE_P(OctantSplit, OctantSplitPaths,
                         ::testing::Values(vfe::kernels::SplitPath::fastest, vfe::kernels::SplitPath::portable));

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

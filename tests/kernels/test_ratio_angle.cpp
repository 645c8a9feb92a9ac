// The exact overlaps' inline atan of a ratio against long double atan2: absolute accuracy
// over ratios from 1e-300 to 1e300, zeros, equal arguments and the table's split points.
#include "ratio_angle.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace {

using vfe::kernels::detail::ratio_angle;
using vfe::kernels::detail::upper_half_angle;

constexpr double kAbsolute = 3e-16;

std::vector<std::pair<double, double>> pairs() {
  std::vector<std::pair<double, double>> p{{0, 0}, {0, 1}, {1, 0}, {1, 1}, {1e-300, 1}, {1, 1e-300}, {5e-324, 1},
                                           {1e300, 1e-300}, {3, 3}};
  for (int k = 0; k <= 8; ++k)  // the table's points k/8 and their neighbours, both ways round
    for (const double q : {k / 8.0, std::nextafter(k / 8.0, 0.0), std::nextafter(k / 8.0, 1.0), k / 8.0 + 1.0 / 16}) {
      p.push_back({q, 1.0});
      p.push_back({1.0, q});
    }
  std::mt19937_64 rng(71);
  std::uniform_real_distribution<double> unit(0.0, 1.0), exponent(-300.0, 300.0);
  for (int i = 0; i < 200000; ++i) {
    const double scale = std::pow(10.0, exponent(rng) / 20);  // most ratios near 1, some far
    p.push_back({unit(rng) * scale, unit(rng)});
    p.push_back({std::pow(10.0, exponent(rng)), std::pow(10.0, exponent(rng))});
  }
  return p;
}

TEST(RatioAngle, AtanOfARatioToAnAbsolute3e16) {
  double worst = 0;
  for (const auto& [num, den] : pairs()) {
    const double got = ratio_angle(num, den);
    const long double want = std::atan2(static_cast<long double>(num), static_cast<long double>(den));
    const double error = static_cast<double>(std::fabs(static_cast<long double>(got) - want));
    worst = std::max(worst, error);
    ASSERT_LE(error, kAbsolute) << num << " / " << den;
  }
  EXPECT_GT(worst, 0.0);  // the reference is long double: the test can see an error
  EXPECT_EQ(ratio_angle(0, 0), 0.0);
}

TEST(RatioAngle, UpperHalfAngleIsAtan2ForEverySignOfX) {
  for (const auto& [num, den] : pairs())
    for (const double x : {den, -den}) {
      if (x == 0 && std::signbit(x)) continue;  // -0 counts as 0 (atan2 would give pi)
      const long double want = std::atan2(static_cast<long double>(num), static_cast<long double>(x));
      ASSERT_LE(std::fabs(static_cast<long double>(upper_half_angle(num, x)) - want), 2 * kAbsolute)
          << num << ", " << x;
    }
}

}  // namespace

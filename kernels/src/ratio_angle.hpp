// atan of a ratio of two non-negative numbers, inline and without branches, to an
// absolute error of about 2e-16: the exact overlaps' angles enter sums with O(1) weights,
// so they need absolute, not relative, accuracy, and libm's atan and atan2 cost several
// times more.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vfe::kernels::detail {

// ratio_angle's atan(k/8) (k = 0..8) then pi/2 - atan(k/8), as unevaluated sums hi + lo.
constexpr double kAngleHi[18] = {
    0x0p+0,               0x1.fd5ba9aac2f6ep-4, 0x1.f5b75f92c80ddp-3,
    0x1.6f61941e4def1p-2, 0x1.dac670561bb4fp-2, 0x1.1e00babdefeb4p-1,
    0x1.4978fa3269ee1p-1, 0x1.700a7c5784634p-1, 0x1.921fb54442d18p-1,
    0x1.921fb54442d18p+0, 0x1.7249faa996a21p+0, 0x1.5368c951e9cfdp+0,
    0x1.3647503caf55cp+0, 0x1.1b6e192ebbe44p+0, 0x1.031f57e54adbep+0,
    0x1.dac670561bb4fp-1, 0x1.b434ee31013fdp-1, 0x1.921fb54442d18p-1};
constexpr double kAngleLo[18] = {
    0x0p+0,                -0x1.cd37686760c17p-59, 0x1.8ab6e3cf7afbdp-57,
    -0x1.c63aae6f6e918p-56, 0x1.a2b7f222f65e2p-56,  -0x1.928df287a668fp-58,
    0x1.2419a87f2a458p-56,  -0x1.8c34d25aadef6p-56, 0x1.1a62633145c07p-55,
    0x1.1a62633145c07p-54,  0x1.a8cc1e7480c68p-54, -0x1.96f47948a99f1p-54,
    0x1.17e21d9a42c9ap-55,  0x1.b1b466a88828ep-54, 0x1.338b4259c027p-54,
    0x1.a2b7f222f65e2p-55,  -0x1.0520d0701d877p-55, 0x1.1a62633145c07p-55};

/// atan(num / den) for num, den >= 0 (both 0: 0), with an absolute error below
/// ~2e-16.  Only absolute accuracy is needed here (all angles enter sums with O(1)
/// weights), which allows a short inline evaluation: reduce to q = min / max in [0, 1],
/// split q around the nearest c = k/8 with atan(q) = atan(c) + atan((q - c) / (1 + qc)),
/// |(q - c) / (1 + qc)| <= 1/16, and sum the odd Taylor series of the remainder to u^13
/// (truncation error < 1e-19).
/// Written without branches (selects and one table), as the exact methods evaluate it many
/// times per sphere on data-dependent ratios whose branches the processor cannot predict.
inline double ratio_angle(double num, double den) {
  // min, max and integer selects, which compile to no branch.
  const int swap = num > den;
  const double small = std::min(num, den), large = std::max(num, den);
  const double q = small / (large + double(large == 0.0));  // num = den = 0 gives 0
  const int k = static_cast<int>(8.0 * q + 0.5);
  const double c = 0.125 * k;
  const double u = (q - c) / (1.0 + q * c);
  const double u2 = u * u;
  const double tail =
      u * u2 *
      (-1.0 / 3 +
       u2 * (1.0 / 5 + u2 * (-1.0 / 7 + u2 * (1.0 / 9 + u2 * (-1.0 / 11 + u2 * (1.0 / 13))))));
  const int at = k + 9 * swap;
  return kAngleHi[at] + (kAngleLo[at] + double(1 - 2 * swap) * (u + tail));
}

/// atan2(y, x) for y >= 0 and any x (-0 counts as 0): an angle in [0, pi], to the same
/// absolute error.
inline double upper_half_angle(double y, double x) {
  const double a = ratio_angle(y, std::fabs(x));
  return x < 0 ? std::numbers::pi - a : a;
}

}  // namespace vfe::kernels::detail

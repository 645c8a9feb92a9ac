// Wall-clock timing of the apps' commands: one clock, milliseconds since a start, medians.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <limits>
#include <vector>

namespace vfe::apps {

using Clock = std::chrono::steady_clock;

/// Milliseconds from t0 to now.
inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// Median of v (the mean of the middle two for an even count); 0 for none.
inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

struct Timing {
  double median_ms = 0, min_ms = 0;
};

/// `rounds` (>= 1) rounds, each timing f(k) once for every k in [0, count) in turn, so
/// that a change in the machine's load falls on every k alike; ms[k][round].
template <class F>
std::vector<std::vector<double>> time_rounds(std::size_t count, int rounds, F&& f) {
  std::vector<std::vector<double>> ms(count);
  for (int i = 0; i < rounds; ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const auto t0 = Clock::now();
      f(k);
      ms[k].push_back(ms_since(t0));
    }
  return ms;
}

/// `repeats` (>= 1) timed calls of f (the caller has warmed it up).
template <class F>
Timing time_calls(int repeats, F&& f) {
  const std::vector<double> ms = time_rounds(1, repeats, [&](std::size_t) { f(); })[0];
  return {median(ms), *std::min_element(ms.begin(), ms.end())};
}

/// The ratios base[i] / ms[i] of the rounds of time_rounds (each taken within a round):
/// their median, least and greatest; NaN for no rounds.
struct RoundRatio {
  double median, min, max;
};
inline RoundRatio round_ratio(const std::vector<double>& base, const std::vector<double>& ms) {
  std::vector<double> ratio;
  for (std::size_t i = 0; i < base.size() && i < ms.size(); ++i) ratio.push_back(base[i] / ms[i]);
  if (ratio.empty()) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    return {nan, nan, nan};
  }
  const auto [lo, hi] = std::minmax_element(ratio.begin(), ratio.end());
  return {median(ratio), *lo, *hi};
}

}  // namespace vfe::apps

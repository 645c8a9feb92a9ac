// The apps' seeded random numbers: splitmix64 (the same stream on every platform, which the
// std distributions are not) and uniformly random rotations.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace vfe::apps {

/// splitmix64 (Steele, Lea and Flood 2014).
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1p-53; }
  /// Uniform in [0, n); the modulo bias is below 2^-40 for n below 2^24.
  std::uint64_t below(std::uint64_t n) { return next() % n; }

 private:
  std::uint64_t state_;
};

/// A unit quaternion (w, x, y, z) uniform over the rotations (Shoemake 1992).
inline std::array<double, 4> random_unit_quaternion(SplitMix64& rng) {
  const double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const double t2 = 2.0 * std::numbers::pi * u2, t3 = 2.0 * std::numbers::pi * u3;
  return {b * std::cos(t3), a * std::sin(t2), a * std::cos(t2), b * std::sin(t3)};
}

}  // namespace vfe::apps

#include <vfe/kernels/particle_template.hpp>
#include <vfe/kernels/v3_clones.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

namespace vfe::kernels {

namespace {

void set_reach(ParticleTemplate& t) {
  t.reach = 0;
  for (const auto& p : t.points) t.reach = std::max(t.reach, p.norm());
}

constexpr double kPi = std::numbers::pi;

// Integral of sqrt(1 - u^2) du (the polar factor sin(theta) of the x, y centroid).
double sin_integral(double u) { return 0.5 * (u * std::sqrt(std::max(0.0, 1.0 - u * u)) + std::asin(u)); }

double shape_penalty(int s, int b, int k) {
  // Near-cubical sub-elements: sectors span twice the polar range of bands, and the
  // radial split is coarser than the polar one (equal-volume shells thin out outwards).
  const double a = std::log(double(k) / (2.0 * b));
  const double c = std::log(double(b) / (2.0 * s));
  return a * a + c * c;
}

}  // namespace

Eigen::Vector3i spherical_layout(int n) {
  n = std::max(n, 1);
  Eigen::Vector3i best(1, 1, n);
  double best_cost = 1e300;
  for (int s = 1; s <= n; ++s) {
    for (int b = 1; s * b <= n; ++b) {
      for (int k : {n / (s * b), n / (s * b) + 1}) {
        if (k < 1) continue;
        const int size = s * b * k;
        const double cost = 20.0 * std::abs(size - n) / n + shape_penalty(s, b, k);
        if (cost < best_cost) {
          best_cost = cost;
          best = Eigen::Vector3i(s, b, k);
        }
      }
    }
  }
  return best;
}

ParticleTemplate make_spherical_template(int n) {
  const Eigen::Vector3i layout = spherical_layout(n);
  const int shells = layout[0], bands = layout[1], sectors = layout[2];
  ParticleTemplate t;
  t.family = "spherical";
  t.shells = shells;
  t.bands = bands;
  t.sectors = sectors;
  const int size = shells * bands * sectors;
  t.points.reserve(size);
  t.fractions.assign(size, 1.0 / size);
  for (int i = 0; i < shells; ++i) {
    const double r0 = std::cbrt(double(i) / shells), r1 = std::cbrt(double(i + 1) / shells);
    // Mean radius of the shell weighted by volume: int r^3 dr / int r^2 dr.
    const double rm = 0.75 * (std::pow(r1, 4) - std::pow(r0, 4)) / (r1 * r1 * r1 - r0 * r0 * r0);
    for (int j = 0; j < bands; ++j) {
      // Equal solid angle: u = cos(theta) equally spaced from 1 to -1.
      const double u0 = 1.0 - 2.0 * j / bands, u1 = 1.0 - 2.0 * (j + 1) / bands;
      const double du = u0 - u1;
      const double mean_sin = (sin_integral(u0) - sin_integral(u1)) / du;
      const double mean_cos = bands == 1 ? 0.0 : 0.5 * (u0 + u1);
      for (int k = 0; k < sectors; ++k) {
        const double p0 = 2.0 * kPi * k / sectors, p1 = 2.0 * kPi * (k + 1) / sectors;
        const double dp = p1 - p0;
        const double mean_cphi = sectors == 1 ? 0.0 : (std::sin(p1) - std::sin(p0)) / dp;
        const double mean_sphi = sectors == 1 ? 0.0 : (std::cos(p0) - std::cos(p1)) / dp;
        t.points.emplace_back(rm * mean_sin * mean_cphi, rm * mean_sin * mean_sphi, rm * mean_cos);
      }
    }
  }
  set_reach(t);
  return t;
}

ParticleTemplate make_fibonacci_template(int n) {
  n = std::max(n, 1);
  ParticleTemplate t;
  t.family = "fibonacci";
  t.fractions.assign(n, 1.0 / n);
  t.points.reserve(n);
  if (n == 1) {
    t.points.emplace_back(0, 0, 0);
    return t;
  }
  // Radial order: rank of the base-2 van der Corput value of i, so that the equal-volume
  // radial strata are visited in an order unrelated to the spiral's polar order.
  std::vector<std::pair<double, int>> vdc(n);
  for (int i = 0; i < n; ++i) {
    double v = 0, f = 0.5;
    for (unsigned m = static_cast<unsigned>(i); m; m >>= 1, f *= 0.5)
      if (m & 1u) v += f;
    vdc[i] = {v, i};
  }
  std::sort(vdc.begin(), vdc.end());
  std::vector<int> stratum(n);
  for (int r = 0; r < n; ++r) stratum[vdc[r].second] = r;
  const double golden_angle = kPi * (3.0 - std::sqrt(5.0));
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const double u = 1.0 - 2.0 * (i + 0.5) / n;
    const double s = std::sqrt(std::max(0.0, 1.0 - u * u));
    const double phi = golden_angle * i;
    // Centroid radius of the equal-volume shell [ (r/n)^(1/3), ((r+1)/n)^(1/3) ].
    const double r0 = std::cbrt(double(stratum[i]) / n), r1 = std::cbrt(double(stratum[i] + 1) / n);
    const double rm = 0.75 * (std::pow(r1, 4) - std::pow(r0, 4)) / (r1 * r1 * r1 - r0 * r0 * r0);
    t.points.emplace_back(rm * s * std::cos(phi), rm * s * std::sin(phi), rm * u);
    mean += t.points.back();
  }
  mean /= n;
  for (auto& p : t.points) p -= mean;
  set_reach(t);
  return t;
}

std::int64_t voxel_count(int m) {
  // Per column (i, j): the k with z^2 <= 1 - x^2 - y^2, counted in closed form.
  std::int64_t count = 0;
  for (int i = 0; i < m; ++i) {
    const double x = double(2 * i + 1) / m - 1.0;
    for (int j = 0; j < m; ++j) {
      const double y = double(2 * j + 1) / m - 1.0;
      const double rest = 1.0 - x * x - y * y;
      if (rest < 0) continue;
      // z = (2k + 1)/m - 1 with |z| <= sqrt(rest): k in [(m(1 - s) - 1)/2, (m(1 + s) - 1)/2].
      const double s = std::sqrt(rest);
      const auto k0 = static_cast<std::int64_t>(std::ceil((m * (1.0 - s) - 1.0) / 2.0));
      const auto k1 = static_cast<std::int64_t>(std::floor((m * (1.0 + s) - 1.0) / 2.0));
      const std::int64_t lo = std::max<std::int64_t>(k0, 0), hi = std::min<std::int64_t>(k1, m - 1);
      if (hi >= lo) count += hi - lo + 1;
    }
  }
  return count;
}

ParticleTemplate make_voxel_template(int n) {
  n = std::max(n, 1);
  // The count grows like (pi / 6) m^3: look around that estimate for the nearest count.
  const int guess = std::max(1, static_cast<int>(std::lround(std::cbrt(6.0 * n / kPi))));
  int best_m = 1;
  std::int64_t best_diff = std::numeric_limits<std::int64_t>::max();
  for (int m = std::max(1, guess - 3); m <= guess + 3; ++m) {
    const std::int64_t diff = std::abs(voxel_count(m) - std::int64_t(n));
    if (diff < best_diff) {
      best_diff = diff;
      best_m = m;
    }
  }
  const int m = best_m;
  ParticleTemplate t;
  t.family = "voxel";
  t.lattice = m;
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const Eigen::Vector3d p(double(2 * i + 1) / m - 1.0, double(2 * j + 1) / m - 1.0,
                                double(2 * k + 1) / m - 1.0);
        // The same test as voxel_count, so the sizes agree exactly.
        const double rest = 1.0 - p[0] * p[0] - p[1] * p[1];
        if (rest >= 0 && std::abs(p[2]) <= std::sqrt(rest)) t.points.push_back(p);
      }
  t.fractions.assign(t.points.size(), 1.0 / double(t.points.size()));
  set_reach(t);
  return t;
}

namespace {

const std::vector<Eigen::Matrix3d>& rotation_bank() {
  static const std::vector<Eigen::Matrix3d> bank = [] {
    std::vector<Eigen::Matrix3d> b(kRotationBankSize);
    for (std::size_t i = 0; i < kRotationBankSize; ++i) b[i] = random_rotation(i, 0x243F6A8885A308D3ull);
    return b;
  }();
  return bank;
}

}  // namespace

const Eigen::Matrix3d& banked_random_rotation(std::uint64_t index, std::uint64_t seed) {
  return rotation_bank()[rotation_bank_slot(index, seed)];
}

const Eigen::Matrix3d& banked_rotation(std::size_t slot) { return rotation_bank()[slot]; }

const float* banked_rotation_rows_table() {
  static const std::vector<float> rows = [] {
    std::vector<float> r(9 * kRotationBankSize);
    for (std::size_t i = 0; i < kRotationBankSize; ++i) rotation_rows(rotation_bank()[i], r.data() + 9 * i);
    return r;
  }();
  return rows.data();
}

const float* banked_random_rotation_rows(std::uint64_t index, std::uint64_t seed) {
  return banked_rotation_rows_table() + 9 * rotation_bank_slot(index, seed);
}

// Built for x86-64-v3 beside the baseline.
VFE_V3_CLONES
void locate_in_block(const ParticleTemplate& tmpl, const Eigen::Vector3d& base, const Eigen::Matrix3d& transform,
                     const std::int64_t m[3], std::int32_t* out) {
  const std::size_t n = tmpl.points.size();
  const double* q = tmpl.points.data()->data();
  const double b0 = base[0], b1 = base[1], b2 = base[2];
  const double t00 = transform(0, 0), t01 = transform(0, 1), t02 = transform(0, 2);
  const double t10 = transform(1, 0), t11 = transform(1, 1), t12 = transform(1, 2);
  const double t20 = transform(2, 0), t21 = transform(2, 1), t22 = transform(2, 2);
  // Clamp in floating point first (to [0, m - 0.5]); truncation then equals floor. The
  // comparisons are written as x86's max/min so they compile to maxpd/minpd.
  const double h0 = double(m[0]) - 0.5, h1 = double(m[1]) - 0.5, h2 = double(m[2]) - 0.5;
  const std::int32_t m0 = static_cast<std::int32_t>(m[0]), m01 = static_cast<std::int32_t>(m[0] * m[1]);
  for (std::size_t s = 0; s < n; ++s) {
    const double x = q[3 * s], y = q[3 * s + 1], z = q[3 * s + 2];
    double u = b0 + t00 * x + t01 * y + t02 * z;
    double v = b1 + t10 * x + t11 * y + t12 * z;
    double w = b2 + t20 * x + t21 * y + t22 * z;
    u = u > 0.0 ? u : 0.0;
    v = v > 0.0 ? v : 0.0;
    w = w > 0.0 ? w : 0.0;
    u = u < h0 ? u : h0;
    v = v < h1 ? v : h1;
    w = w < h2 ? w : h2;
    out[s] = static_cast<std::int32_t>(u) + m0 * static_cast<std::int32_t>(v) + m01 * static_cast<std::int32_t>(w);
  }
}

Eigen::Matrix3d random_rotation(std::uint64_t index, std::uint64_t seed) {
  // splitmix64 stream keyed by (index, seed): stateless, so any thread computes the
  // same rotation for a particle.
  std::uint64_t state = index * 0x9E3779B97F4A7C15ull ^ (seed + 0x632BE59BD9B4E019ull);
  auto next = [&state]() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return double(z >> 11) * 0x1.0p-53;
  };
  // Shoemake's uniform random unit quaternion.
  const double u1 = next(), u2 = next(), u3 = next();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const Eigen::Quaterniond q(b * std::cos(2 * kPi * u3), a * std::sin(2 * kPi * u2),
                             a * std::cos(2 * kPi * u2), b * std::sin(2 * kPi * u3));
  return q.toRotationMatrix();
}

}  // namespace vfe::kernels

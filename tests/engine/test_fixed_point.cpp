// deterministic=1 sums every cell in fixed point: the field must not depend on the order in
// which a cell's deposits arrive (thread count, particle order, which engine of a split
// computed them), incremental must equal a fresh compute, and the sums stay within rounding
// of the double sums. Oracles: the same particles in another order, the sum of two halves
// computed apart, and the exact overlap's total volume.
#include "particles.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <string>
#include <vector>

namespace vfe::test {
namespace {

/// The particles of the packed bed with ids, and the grid of chi = 2 around them.
struct Scene {
  Particles p;
  std::vector<std::int64_t> ids;
  CartesianGridSpec g;
};

Scene bed(std::size_t n) {
  Scene s;
  s.p = packed_bed(n);
  s.ids.resize(s.p.radii.size());
  std::iota(s.ids.begin(), s.ids.end(), 1000);
  const double h = 2e-3;  // chi = 2 for d = 1 mm
  s.g = grid(h, 0, 0, 0);
  double hi[3] = {0, 0, 0};
  for (std::size_t i = 0; i < s.p.radii.size(); ++i)
    for (int d = 0; d < 3; ++d) hi[d] = std::max(hi[d], s.p.centres[3 * i + d] + s.p.radii[i]);
  for (int d = 0; d < 3; ++d) {
    s.g.origin[d] = -h;
    s.g.cells[d] = static_cast<std::int64_t>(std::ceil(hi[d] / h)) + 2;
  }
  return s;
}

/// The scene's particles in the order `order` (ids follow their particles).
Scene permuted(const Scene& s, const std::vector<std::size_t>& order) {
  Scene t{{}, {}, s.g};
  for (const std::size_t i : order) {
    t.p.add(s.p.centres[3 * i], s.p.centres[3 * i + 1], s.p.centres[3 * i + 2], s.p.radii[i]);
    t.ids.push_back(s.ids[i]);
  }
  return t;
}

std::vector<double> compute(Engine& e, const Scene& s) {
  vfe_particles v{};
  v.n = static_cast<std::int64_t>(s.p.radii.size());
  v.centres = s.p.centres.data();
  v.radii = s.p.radii.data();
  v.ids = s.ids.data();
  std::vector<double> out(static_cast<std::size_t>(e.cell_count()));
  e.compute(v, out);
  return out;
}

bool bitwise_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

std::vector<std::size_t> shuffled(std::size_t n, unsigned seed) {
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  return order;
}

const char* const kMethods[] = {"direct", "pmm", "exact", "divided", "gaussian", "porous_cube", "big_particle",
                                "trilinear"};

TEST(FixedPoint, FieldIsTheSameForAnyParticleOrderAndThreadCount) {
  const Scene s = bed(3000);
  const Scene t = permuted(s, shuffled(s.p.radii.size(), 7));
  for (const char* method : kMethods) {
    SCOPED_TRACE(method);
    Engine e(s.g);
    e.configure(std::string("deterministic=1 outside=nearest threads=2 method=") + method);
    const std::vector<double> a = compute(e, s), b = compute(e, t);
    e.configure("threads=1");
    const std::vector<double> c = compute(e, t);
    EXPECT_TRUE(bitwise_equal(a, b)) << "particle order changed the deterministic field";
    EXPECT_TRUE(bitwise_equal(a, c)) << "thread count changed the deterministic field";
    // Within rounding of the double sums, and conserving the volume.
    Engine plain(s.g);
    plain.configure(std::string("outside=nearest method=") + method);
    const std::vector<double> d = compute(plain, s);
    const double vp = s.p.volume() / double(s.p.radii.size());
    double worst = 0, total = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      worst = std::max(worst, std::abs(a[i] - d[i]));
      total += a[i];
    }
    EXPECT_LT(worst, 1e-13 * vp);
    EXPECT_NEAR(total, s.p.volume(), 1e-12 * s.p.volume());
  }
}

TEST(FixedPoint, TwoHalvesComputedApartAddToTheWhole) {
  // What a distributed mesh relies on: each rank sums its particles in the same unit, and the
  // owner adds the integers.
  const Scene s = bed(2000);
  const Scene t = permuted(s, shuffled(s.p.radii.size(), 11));
  const std::size_t half = t.p.radii.size() / 2;
  std::vector<std::size_t> first(half), second(t.p.radii.size() - half);
  std::iota(first.begin(), first.end(), 0);
  std::iota(second.begin(), second.end(), half);
  vfe_particles all{};
  all.n = static_cast<std::int64_t>(s.p.radii.size());
  all.centres = s.p.centres.data();
  all.radii = s.p.radii.data();
  const double largest = Engine(s.g).largest_particle_volume(all);
  for (const char* method : {"pmm", "exact", "gaussian"}) {
    SCOPED_TRACE(method);
    Engine whole(s.g), a(s.g), b(s.g);
    for (Engine* e : {&whole, &a, &b}) {
      e->configure(std::string("deterministic=1 outside=nearest method=") + method);
      e->set_deterministic_volume(largest);
    }
    const std::vector<double> field = compute(whole, s);
    compute(a, permuted(t, first));
    compute(b, permuted(t, second));
    const Engine::FixedField fw = whole.fixed_solid(), fa = a.fixed_solid(), fb = b.fixed_solid();
    ASSERT_EQ(fa.exponent, fw.exponent);
    ASSERT_EQ(fb.exponent, fw.exponent);
    std::vector<double> added(field.size());
    for (std::size_t c = 0; c < field.size(); ++c) {
      ASSERT_TRUE(fa.sums[c] + fb.sums[c] == fw.sums[c]) << "cell " << c;
      added[c] = from_fixed(fa.sums[c] + fb.sums[c], fw.exponent);
    }
    EXPECT_TRUE(bitwise_equal(added, field));
  }
}

TEST(FixedPoint, IncrementalEqualsAFreshCompute) {
  const Scene s = bed(2000);
  Scene moved = s;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-2e-4, 2e-4);
  for (std::size_t i = 0; i < moved.p.radii.size(); i += 7)
    for (int d = 0; d < 3; ++d) moved.p.centres[3 * i + d] += jitter(rng);
  for (const char* method : {"pmm", "exact", "direct"}) {
    SCOPED_TRACE(method);
    Engine inc(s.g), fresh(s.g);
    inc.configure(std::string("deterministic=1 incremental=1 outside=nearest method=") + method);
    fresh.configure(std::string("deterministic=1 outside=nearest method=") + method);
    compute(inc, s);
    const std::vector<double> a = compute(inc, moved), b = compute(fresh, moved);
    EXPECT_GT(inc.last_report_value("moved_particles"), 0);
    EXPECT_LT(inc.last_report_value("moved_particles"), double(s.p.radii.size()));
    EXPECT_TRUE(bitwise_equal(a, b)) << "incremental drifted from a fresh compute";
    // Back to the first positions: the first field, bit for bit.
    EXPECT_TRUE(bitwise_equal(compute(inc, s), compute(fresh, s)));
  }
}

TEST(FixedPoint, TouchedOnlyGivesTheSameField) {
  const Scene s = bed(1500);
  Engine a(s.g), b(s.g);
  a.configure("deterministic=1 method=pmm outside=nearest");
  b.configure("deterministic=1 touched_only=1 method=pmm outside=nearest");
  const std::vector<double> fa = compute(a, s);
  EXPECT_TRUE(bitwise_equal(fa, compute(b, s)));
  EXPECT_TRUE(bitwise_equal(fa, compute(b, s)));  // the second compute clears what the first left
}

TEST(FixedPoint, DepositIsTheSameForAnyParticleOrder) {
  const Scene s = bed(2000);
  const std::vector<std::size_t> order = shuffled(s.p.radii.size(), 5);
  const Scene t = permuted(s, order);
  const std::size_t n = s.p.radii.size();
  std::vector<double> values(3 * n), values_t(3 * n);
  std::mt19937 rng(9);
  std::normal_distribution<double> speed(0.0, 0.3);
  for (double& v : values) v = speed(rng);
  for (std::size_t i = 0; i < n; ++i)
    for (int j = 0; j < 3; ++j) values_t[3 * i + j] = values[3 * order[i] + j];
  for (const char* method : {"pmm", "exact"}) {
    SCOPED_TRACE(method);
    Engine e(s.g);
    e.configure(std::string("deterministic=1 weights=1 outside=nearest method=") + method);
    const std::size_t nc = static_cast<std::size_t>(e.cell_count());
    std::vector<double> a(3 * nc), b(3 * nc), plain(3 * nc);
    compute(e, s);
    e.deposit(3, values, a);
    compute(e, t);
    e.deposit(3, values_t, b);
    EXPECT_TRUE(bitwise_equal(a, b));
    e.configure("deterministic=0");
    compute(e, s);
    e.deposit(3, values, plain);
    double worst = 0, largest = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      worst = std::max(worst, std::abs(a[i] - plain[i]));
      largest = std::max(largest, std::abs(plain[i]));
    }
    EXPECT_LT(worst, 1e-14 * largest);
    // A value the fixed-point sums cannot hold is refused with a message, not summed.
    e.configure("deterministic=1");
    compute(e, s);
    std::vector<double> bad = values;
    bad[4] = std::numeric_limits<double>::infinity();
    std::vector<double> untouched(3 * nc, -1.0);
    try {
      e.deposit(3, bad, untouched);
      ADD_FAILURE() << "an infinite value was deposited";
    } catch (const Error& err) {
      EXPECT_NE(std::string(err.what()).find("particle 1"), std::string::npos) << err.what();
    }
    EXPECT_TRUE(std::all_of(untouched.begin(), untouched.end(), [](double x) { return x == -1.0; }));
  }
}

TEST(FixedPoint, FixedFieldNeedsADeterministicCompute) {
  const Scene s = bed(100);
  Engine e(s.g);
  e.configure("outside=nearest");
  compute(e, s);
  EXPECT_THROW(e.fixed_solid(), Error);
}

}  // namespace
}  // namespace vfe::test

// particle_order=blocked (the spheres computed in slabs of the field) against the host's
// order (particle_order=input), a separate code path over the same drivers: the fields must
// agree to the summation's round-off, and bitwise with deterministic=1; what names a particle
// (errors, rotation keys) must use the host's index or id.
#include "particles.hpp"
#include "particle_order.hpp"

#include <vfe/vfe.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace vfe::test {
namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

/// A 48^3 grid of unit cells: a field of 864 KiB, ordered in 14 slabs of 64 KiB.
CartesianGridSpec grid48() { return grid(1.0, 48, 48, 48); }

/// Fields equal up to the order of summation: a cell's sum of a few hundred deposits moves
/// by a few ulps of its value, far below one deposit (V/n of a particle).
void expect_same_up_to_round_off(const std::vector<double>& a, const std::vector<double>& b, double particle_volume,
                                 const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  int bad = 0;
  for (std::size_t c = 0; c < a.size() && bad < 5; ++c)
    if (!(std::abs(a[c] - b[c]) <= 1e-12 * (std::abs(b[c]) + particle_volume))) {
      ADD_FAILURE() << what << ": cell " << c << ": " << a[c] << " against " << b[c];
      ++bad;
    }
}

bool bitwise_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

std::vector<double> compute_with_ids(Engine& e, const Particles& p, const std::vector<std::int64_t>& ids,
                                     const std::string& options) {
  e.configure(options);
  vfe_particles v{};
  v.n = static_cast<std::int64_t>(p.radii.size());
  v.centres = p.centres.data();
  v.radii = p.radii.data();
  v.ids = ids.data();
  std::vector<double> out(static_cast<std::size_t>(e.cell_count()), -1.0);
  e.compute(v, out);
  return out;
}

TEST(ParticleOrder, BlockedEqualsInputForEveryMethod) {
  // Spheres of chi 0.7 to 2.5, some beyond the grid (outside=nearest), in random order.
  const Particles p = random_spheres(41, 20000, -1.0, 49.0, 0.2, 0.7);
  const double v = p.volume() / double(p.radii.size());
  for (const std::string_view method : method_names()) {
    SCOPED_TRACE(std::string(method));
    Engine in_order(grid48()), blocked(grid48());
    const std::string common = "method=" + std::string(method) + " threads=2";
    const std::vector<double> a = run(in_order, p, common + " particle_order=input");
    const std::vector<double> b = run(blocked, p, common + " particle_order=blocked");
    EXPECT_EQ(in_order.last_report_value("ordered_blocks"), 0.0);
    EXPECT_EQ(blocked.last_report_value("ordered_blocks"), 14.0);
    expect_same_up_to_round_off(b, a, v, std::string(method));
    const Report& ra = in_order.last_report();
    const Report& rb = blocked.last_report();
    EXPECT_EQ(rb.sub_elements, ra.sub_elements);
    EXPECT_EQ(rb.fast_path_particles, ra.fast_path_particles);
    EXPECT_EQ(rb.outside_particles, ra.outside_particles);
    EXPECT_GT(ra.outside_particles, 0);
    EXPECT_NEAR(rb.particle_volume, ra.particle_volume, 1e-12 * ra.particle_volume);
    EXPECT_NEAR(rb.deposited_volume, ra.deposited_volume, 1e-12 * ra.particle_volume);
  }
}

TEST(ParticleOrder, DeterministicIsBitwiseEqualForOneAndTwoThreads) {
  const Particles p = random_spheres(42, 20000, -1.0, 49.0, 0.2, 0.7);
  for (const char* method : {"direct", "pmm", "exact", "gaussian", "auto"}) {
    SCOPED_TRACE(method);
    Engine reference(grid48());
    const std::vector<double> ref =
        run(reference, p, std::string("deterministic=1 threads=1 particle_order=input method=") + method);
    for (const char* threads : {"1", "2"}) {
      SCOPED_TRACE(threads);
      Engine e(grid48());
      const std::vector<double> f =
          run(e, p, std::string("deterministic=1 particle_order=blocked threads=") + threads + " method=" + method);
      EXPECT_EQ(e.last_report_value("ordered_blocks"), 14.0);
      EXPECT_TRUE(bitwise_equal(f, ref));
    }
  }
}

TEST(ParticleOrder, ErrorsNameTheHostsIndex) {
  Particles p = random_spheres(43, 20000, 2.0, 46.0, 0.2, 0.4);
  {
    Particles bad = p;
    bad.radii[777] = std::numeric_limits<double>::quiet_NaN();
    Engine e(grid48());
    e.configure("method=pmm particle_order=blocked");
    std::vector<double> out(static_cast<std::size_t>(e.cell_count()), -1.0);
    try {
      e.compute(bad.view(), out);
      ADD_FAILURE() << "a NaN radius was accepted";
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_EQ(std::string(err.what()).rfind("particle 777: ", 0), 0u) << err.what();
    }
    EXPECT_EQ(out[0], -1.0);  // the output is untouched
  }
  // Two particles beyond the grid's x faces: host index 300 in the top slab (late in the
  // blocked order), 5000 in the bottom one (early). The first by the host's index is 300.
  p.centres[3 * 300] = -0.2, p.centres[3 * 300 + 2] = 45.0;
  p.centres[3 * 5000] = 48.1, p.centres[3 * 5000 + 2] = 3.0;
  for (const char* method : {"direct", "pmm", "exact"}) {
    SCOPED_TRACE(method);
    Engine e(grid48());
    e.configure(std::string("outside=error particle_order=blocked method=") + method);
    std::vector<double> out(static_cast<std::size_t>(e.cell_count()), -1.0);
    try {
      e.compute(p.view(), out);
      ADD_FAILURE() << "particles beyond the grid were accepted";
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_OUT_OF_DOMAIN);
      EXPECT_EQ(std::string(err.what()).rfind("particle 300 at (-0.2, ", 0), 0u) << err.what();
    }
    EXPECT_EQ(out[0], -1.0);
    // The engine stays usable, in the blocked order.
    p.centres[3 * 300] = 10.0, p.centres[3 * 5000] = 10.0;
    e.compute(p.view(), out);
    EXPECT_EQ(e.last_report_value("ordered_blocks"), 14.0);
    EXPECT_NEAR(total(out), p.volume(), 1e-12 * p.volume());
    p.centres[3 * 300] = -0.2, p.centres[3 * 5000] = 48.1;
  }
}

TEST(ParticleOrder, RotationsKeyOnTheHostsIdOrIndex) {
  // chi = 1 and below: a rotation moves sub-elements across faces, so a particle that took
  // another's key would change the field far beyond round-off.
  const Particles p = random_spheres(44, 20000, 1.0, 47.0, 0.5, 0.9);
  const double v = p.volume() / double(p.radii.size());
  std::vector<std::int64_t> ids(p.radii.size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<std::int64_t>(3 * (ids.size() - i) + 7);
  for (const char* method : {"pmm", "divided", "auto"}) {
    SCOPED_TRACE(method);
    Engine a(grid48()), b(grid48());
    const std::string common = std::string("threads=2 method=") + method;
    const std::vector<double> by_index = run(a, p, common + " particle_order=input");
    expect_same_up_to_round_off(run(b, p, common + " particle_order=blocked"), by_index, v, "by index");
    const std::vector<double> by_id = compute_with_ids(a, p, ids, common + " particle_order=input");
    expect_same_up_to_round_off(compute_with_ids(b, p, ids, common + " particle_order=blocked"), by_id, v, "by id");
    EXPECT_EQ(b.last_report_value("ordered_blocks"), 14.0);
    if (std::string(method) == "pmm") EXPECT_GT(l1(by_id, by_index), 1e-4 * p.volume());
    if (std::string(method) == "auto") {  // only its spheres on pmm's path rotate (divided is never rotated)
      ASSERT_GT(b.last_report_value("auto_pmm"), 0.0);
      EXPECT_GT(l1(by_id, by_index), 1e-9 * p.volume());
    }
  }
}

TEST(ParticleOrder, WeightsAndIncrementalKeepTheHostsOrder) {
  Particles p = random_spheres(45, 20000, 1.0, 47.0, 0.2, 0.7);
  for (const char* option : {"weights=1", "incremental=1"}) {
    SCOPED_TRACE(option);
    Engine in_order(grid48()), blocked(grid48());
    const std::string common = std::string("method=pmm threads=1 ") + option;  // one thread: the same sums
    const std::vector<double> a = run(in_order, p, common + " particle_order=input");
    const std::vector<double> b = run(blocked, p, common + " particle_order=blocked");
    EXPECT_EQ(blocked.last_report_value("ordered_blocks"), 0.0);  // they keep deposits by the host's index
    EXPECT_TRUE(bitwise_equal(a, b));
  }
  // A deterministic incremental engine that moves one particle equals a fresh blocked compute.
  Engine inc(grid48()), fresh(grid48());
  run(inc, p, "method=pmm deterministic=1 incremental=1 particle_order=blocked");
  p.centres[3 * 123] += 2.5;
  std::vector<double> moved(static_cast<std::size_t>(inc.cell_count()));
  inc.compute(p.view(), moved);
  EXPECT_EQ(inc.last_report_value("moved_particles"), 1.0);
  const std::vector<double> ref = run(fresh, p, "method=pmm deterministic=1 particle_order=blocked");
  EXPECT_EQ(fresh.last_report_value("ordered_blocks"), 14.0);
  EXPECT_TRUE(bitwise_equal(moved, ref));
}

TEST(ParticleOrder, PeriodicGridsAndOtherMeshes) {
  const Particles spill = random_spheres(46, 20000, -2.0, 50.0, 0.2, 0.7);
  const double v = spill.volume() / double(spill.radii.size());
  for (const char* method : {"direct", "pmm", "exact", "gaussian", "trilinear"}) {
    SCOPED_TRACE(method);
    Engine a(grid48()), b(grid48());
    const std::string common = std::string("periodic=xyz method=") + method;
    const std::vector<double> fa = run(a, spill, common + " particle_order=input");
    expect_same_up_to_round_off(run(b, spill, common + " particle_order=blocked"), fa, v, "periodic");
    EXPECT_EQ(b.last_report_value("ordered_blocks"), 14.0);
    EXPECT_NEAR(total(fa), spill.volume(), 1e-12 * spill.volume());
  }
  // A graded rectilinear grid: slabs of the box, cells of unequal layers.
  std::array<std::vector<double>, 3> nodes;
  for (auto& axis : nodes)
    for (int i = 0; i <= 48; ++i) axis.push_back(48.0 * std::pow(i / 48.0, 1.3));
  for (const char* method : {"pmm", "exact", "big_particle"}) {
    SCOPED_TRACE(method);
    Engine a(RectilinearGridSpec{nodes}), b(RectilinearGridSpec{nodes});
    const std::vector<double> fa = run(a, spill, std::string("particle_order=input method=") + method);
    expect_same_up_to_round_off(run(b, spill, std::string("particle_order=blocked method=") + method), fa, v,
                                "rectilinear");
    EXPECT_EQ(b.last_report_value("ordered_blocks"), 14.0);
  }
  // An OpenFOAM polyMesh (its general path): two slabs of its box.
  Particles bed = random_spheres(47, 3000, 0.0, 0.02, 0.0004, 0.0008);
  for (std::size_t i = 0; i < bed.radii.size(); ++i) bed.centres[3 * i + 2] *= 3;  // the box is 20 x 20 x 60 mm
  for (const char* method : {"pmm", "exact", "divided"}) {
    SCOPED_TRACE(method);
    const PolyMeshSpec box{kData + "openfoam/box_uniform_10x10x30"};
    Engine a(box), b(box);
    const std::vector<double> fa = run(a, bed, std::string("lattice=0 particle_order=input method=") + method);
    expect_same_up_to_round_off(run(b, bed, std::string("lattice=0 particle_order=blocked method=") + method), fa,
                                bed.volume() / 3000.0, "polyMesh");
    EXPECT_EQ(b.last_report_value("ordered_blocks"), 2.0);
  }
}

TEST(ParticleOrder, AutoOrdersLargeFieldsOnlyAndNotForDirect) {
  // 64 x 64 x 48 cells: a field of kAutoFieldBytes (1.5 MiB), in 24 slabs of 64 KiB.
  static_assert(detail::kAutoFieldBytes == 8 * 64 * 64 * 48);
  const Particles many = random_spheres(48, int(detail::kAutoParticles), 1.0, 47.0, 0.2, 0.4);
  Particles fewer = many;
  fewer.radii.pop_back(), fewer.centres.resize(fewer.centres.size() - 3);
  struct Case {
    const char* name;
    CartesianGridSpec grid;
    const Particles* p;
    std::string options;
    double blocks;
  };
  const Case cases[] = {
      {"large", grid(1.0, 64, 64, 48), &many, "method=pmm", 24},
      {"large, exact", grid(1.0, 64, 64, 48), &many, "method=exact", 24},
      {"large, direct", grid(1.0, 64, 64, 48), &many, "method=direct", 0},
      {"one particle fewer", grid(1.0, 64, 64, 48), &fewer, "method=pmm", 0},
      {"one layer fewer", grid(1.0, 64, 64, 47), &many, "method=pmm", 0},
      {"large, weights", grid(1.0, 64, 64, 48), &many, "method=pmm weights=1", 0},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    Engine e(c.grid);
    const std::vector<double> f = run(e, *c.p, c.options + " orientation=none");
    EXPECT_EQ(e.option("particle_order"), "auto");
    EXPECT_EQ(e.last_report_value("ordered_blocks"), c.blocks);
    EXPECT_NEAR(total(f), c.p->volume(), 1e-12 * c.p->volume());
  }
}

}  // namespace
}  // namespace vfe::test

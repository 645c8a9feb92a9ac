// The coupling API: per-particle weights, deposit and interpolate (their identities on every
// method and mesh kind), meshes from the host's arrays, and particle views over the host's
// own layout.
#include "particles.hpp"
#include "polymesh/polymesh.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

namespace vfe::test {
namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

struct Csr {
  std::vector<std::int64_t> offsets, cells;
  std::vector<double> fractions;
};

Csr weights_of(const Engine& e) {
  const Engine::WeightsSize size = e.weights_size();
  Csr w;
  w.offsets.resize(static_cast<std::size_t>(size.particles + 1));
  w.cells.resize(static_cast<std::size_t>(size.entries));
  w.fractions.resize(static_cast<std::size_t>(size.entries));
  e.weights(w.offsets, w.cells, w.fractions);
  return w;
}

double sphere_volume(double r) { return 4.0 / 3.0 * std::numbers::pi * r * r * r; }

/// The identities of the weights and of deposit/interpolate for engine e after a compute of
/// p that gave `solid` with `dropped` volume lost: returns the worst relative residual.
double check_identities(const Engine& e, const Particles& p, const std::vector<double>& solid) {
  const Csr w = weights_of(e);
  const std::int64_t n = static_cast<std::int64_t>(p.radii.size()), nc = e.cell_count();
  EXPECT_EQ(static_cast<std::int64_t>(w.offsets.size()), n + 1);
  double worst = 0;
  const double vtot = p.volume();
  // Fractions of a particle sum to 1 (outside=nearest/centre drop nothing) and rebuild the field.
  std::vector<double> rebuilt(static_cast<std::size_t>(nc), 0.0);
  for (std::int64_t q = 0; q < n; ++q) {
    double sum = 0;
    for (std::int64_t k = w.offsets[q]; k < w.offsets[q + 1]; ++k) {
      sum += w.fractions[k];
      rebuilt[w.cells[k]] += w.fractions[k] * sphere_volume(p.radii[q]);
    }
    worst = std::max(worst, std::abs(sum - 1.0));
  }
  for (std::int64_t c = 0; c < nc; ++c) worst = std::max(worst, std::abs(rebuilt[c] - solid[c]) / vtot);
  // deposit of V_p is the solid field; deposit of a 3-vector conserves its sum.
  std::vector<double> vols(static_cast<std::size_t>(n)), force(static_cast<std::size_t>(3 * n));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (std::int64_t q = 0; q < n; ++q) {
    vols[q] = sphere_volume(p.radii[q]);
    for (int j = 0; j < 3; ++j) force[3 * q + j] = u(rng);
  }
  std::vector<double> out(static_cast<std::size_t>(nc)), out3(static_cast<std::size_t>(3 * nc));
  e.deposit(1, vols, out);
  for (std::int64_t c = 0; c < nc; ++c) worst = std::max(worst, std::abs(out[c] - solid[c]) / vtot);
  e.deposit(3, force, out3);
  for (int j = 0; j < 3; ++j) {
    double a = 0, b = 0, scale = 0;
    for (std::int64_t q = 0; q < n; ++q) a += force[3 * q + j], scale += std::abs(force[3 * q + j]);
    for (std::int64_t c = 0; c < nc; ++c) b += out3[3 * c + j];
    worst = std::max(worst, std::abs(a - b) / scale);
  }
  // interpolate: a constant field comes back exactly; <deposit(f), g> = <f, interpolate(g)>
  // (every particle is wholly covered here).
  std::vector<double> field(static_cast<std::size_t>(3 * nc)), at(static_cast<std::size_t>(3 * n));
  for (std::int64_t c = 0; c < nc; ++c)
    for (int j = 0; j < 3; ++j) field[3 * c + j] = 2.5 + j;
  e.interpolate(3, field, at);
  for (std::int64_t q = 0; q < n; ++q)
    for (int j = 0; j < 3; ++j) worst = std::max(worst, std::abs(at[3 * q + j] - (2.5 + j)) / 2.5);
  for (auto& x : field) x = u(rng);
  e.interpolate(3, field, at);
  double lhs = 0, rhs = 0, scale = 0;
  for (std::int64_t c = 0; c < 3 * nc; ++c) lhs += out3[c] * field[c], scale += std::abs(out3[c] * field[c]);
  for (std::int64_t q = 0; q < 3 * n; ++q) rhs += force[q] * at[q];
  worst = std::max(worst, std::abs(lhs - rhs) / scale);
  return worst;
}

TEST(Coupling, WeightsDepositAndInterpolateIdentitiesOnEveryMethodAndMesh) {
  std::vector<std::unique_ptr<Engine>> engines;
  engines.push_back(std::make_unique<Engine>(grid(0.002, 10, 10, 30)));
  std::vector<double> z(31);
  for (int i = 0; i <= 30; ++i) z[i] = 0.06 * std::pow(i / 30.0, 1.3);
  std::vector<double> xy(11);
  for (int i = 0; i <= 10; ++i) xy[i] = 0.002 * i;
  engines.push_back(std::make_unique<Engine>(RectilinearGridSpec{{xy, xy, z}}));
  engines.push_back(std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"}));
  engines.push_back(std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"}));
  const Particles p = random_spheres(9, 400, 0.005, 0.015, 0.0004, 0.0012);
  double worst = 0;
  for (auto& e : engines) {
    for (const std::string_view m : method_names()) {
      const std::string opts = "method=" + std::string(m) + " weights=1 outside=nearest particle_grid=50";
      try {
        e->configure(opts);
      } catch (const Error& err) {
        ASSERT_EQ(err.status(), VFE_ERROR_UNSUPPORTED) << m;  // not on this mesh kind
        continue;
      }
      SCOPED_TRACE(std::string(m) + " on " + std::to_string(e->cell_count()) + " cells");
      std::vector<double> solid(e->cell_count());
      e->compute(p.view(), solid);
      const double r = check_identities(*e, p, solid);
      EXPECT_LT(r, 1e-12);
      worst = std::max(worst, r);
    }
  }
  RecordProperty("worst_identity_residual", std::to_string(worst));
}

TEST(Coupling, WeightsAfterIncrementalAndDeterministicComputes) {
  Engine e(grid(0.002, 10, 10, 10));
  Particles p = random_spheres(2, 500, 0.002, 0.018, 0.0003, 0.0008);
  for (const char* opts : {"weights=1 incremental=1", "weights=1 deterministic=1 threads=2"}) {
    SCOPED_TRACE(opts);
    std::vector<double> solid = run(e, p, std::string("method=exact ") + opts);
    EXPECT_LT(check_identities(e, p, solid), 1e-12);
    p.centres[0] += 1e-4;  // one particle moves
    e.compute(p.view(), solid);
    EXPECT_LT(check_identities(e, p, solid), 1e-12);
  }
}

TEST(Coupling, DroppedShareAndBadCalls) {
  Engine e(grid(1, 4, 4, 4));
  std::vector<double> out(e.cell_count()), big(3 * e.cell_count());
  // Before any compute, and after one without weights: a clear error, outputs untouched.
  for (int step = 0; step < 2; ++step) {
    try {
      e.deposit(1, std::vector<double>(), out);
      FAIL();
    } catch (const Error& err) {
      EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_NE(std::string(err.what()).find("weights=1"), std::string::npos) << err.what();
    }
    Particles p;
    p.add(2, 2, 2, 0.4);
    if (step == 0) (void)run(e, p, "method=exact");
  }
  // A particle half beyond the mesh under outside=drop: its fractions sum to the kept share.
  Particles p;
  p.add(0.0, 2.0, 2.0, 0.5);
  const std::vector<double> solid = run(e, p, "method=exact weights=1 outside=drop");
  const Csr w = weights_of(e);
  const double kept = std::accumulate(w.fractions.begin(), w.fractions.end(), 0.0);
  EXPECT_NEAR(kept, 0.5, 1e-12);
  EXPECT_NEAR(e.last_report().dropped_volume, 0.5 * p.volume(), 1e-12);
  // interpolate normalises by the covered share: a constant comes back exactly.
  std::vector<double> field(e.cell_count(), 4.0), at(1);
  e.interpolate(1, field, at);
  EXPECT_NEAR(at[0], 4.0, 1e-12);
  // Wrong sizes and component counts are named.
  EXPECT_THROW(e.deposit(1, std::vector<double>(2), out), Error);
  EXPECT_THROW(e.deposit(0, std::vector<double>(), out), Error);
  EXPECT_THROW(e.interpolate(3, field, at), Error);
}

/// The polyMesh of a case folder as the host's arrays.
struct MeshArrays {
  std::vector<double> points;
  std::vector<std::int64_t> offsets, face_points, owner, neighbour;
  PolyMeshArrays view() const {
    PolyMeshArrays a;
    a.n_points = static_cast<std::int64_t>(points.size() / 3);
    a.points = points.data();
    a.n_faces = static_cast<std::int64_t>(owner.size());
    a.face_offsets = offsets.data();
    a.face_points = face_points.data();
    a.owner = owner.data();
    a.n_internal_faces = static_cast<std::int64_t>(neighbour.size());
    a.neighbour = neighbour.data();
    return a;
  }
};

MeshArrays arrays_of(const PolyMesh& m) {
  MeshArrays a;
  for (const auto& x : m.points()) a.points.insert(a.points.end(), {x[0], x[1], x[2]});
  a.offsets.push_back(0);
  for (std::int64_t f = 0; f < m.face_count(); ++f) {
    for (const std::int64_t q : m.face(f)) a.face_points.push_back(q);
    a.offsets.push_back(static_cast<std::int64_t>(a.face_points.size()));
    a.owner.push_back(m.owner(f));
    if (f < m.internal_face_count()) a.neighbour.push_back(m.neighbour(f));
  }
  return a;
}

TEST(Coupling, ArraysMeshEqualsFolderMeshOnTheFourMeshes) {
  const Particles p = random_spheres(4, 300, 0.003, 0.017, 0.0003, 0.0009);
  for (const char* mesh : {"box_uniform_10x10x30", "box_graded", "cylinder_ogrid_coarse", "snappy_obstacle"}) {
    SCOPED_TRACE(mesh);
    const std::string dir = kData + "openfoam/" + mesh;
    Engine folder(PolyMeshSpec{dir});
    const MeshArrays a = arrays_of(PolyMesh::read(dir));
    Engine arrays(a.view());
    ASSERT_EQ(arrays.cell_count(), folder.cell_count());
    std::vector<double> va(arrays.cell_count()), vf(folder.cell_count());
    arrays.cell_volumes(va);
    folder.cell_volumes(vf);
    EXPECT_EQ(va, vf);
    for (const char* m : {"method=pmm deterministic=1", "method=exact deterministic=1",
                          "method=big_particle deterministic=1"}) {
      EXPECT_EQ(run(arrays, p, m), run(folder, p, m)) << m;
    }
  }
  // Bad arrays are named.
  MeshArrays bad = arrays_of(PolyMesh::read(kData + "openfoam/box_uniform_10x10x30"));
  bad.face_points[5] = 1 << 30;
  try {
    Engine e(bad.view());
    FAIL();
  } catch (const Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(err.what()).find("point label"), std::string::npos) << err.what();
  }
}

// The host's array of structs, read in place through byte strides; host ids keep a
// particle's template rotation when the host reorders its particles.
TEST(Coupling, StridedViewOverArrayOfStructsAndIdsKeepRotations) {
  struct HostParticle {
    double x[3];
    double velocity[3];
    double radius;
    std::int64_t id;
  };
  const Particles p = random_spheres(8, 700, 0.001, 0.019, 0.0003, 0.0009);
  std::vector<HostParticle> host(p.radii.size());
  for (std::size_t i = 0; i < host.size(); ++i) {
    host[i] = {{p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2]}, {1, 2, 3}, p.radii[i],
               static_cast<std::int64_t>(1000 + i)};
  }
  Engine e(grid(0.002, 10, 10, 10));
  e.configure("method=pmm particle_grid=30");
  std::vector<double> packed(e.cell_count()), strided(e.cell_count()), reordered(e.cell_count());
  vfe_particles v{};
  v.n = static_cast<std::int64_t>(host.size());
  v.centres = host[0].x;
  v.centres_stride = sizeof(HostParticle);
  v.radii = &host[0].radius;
  v.radii_stride = sizeof(HostParticle);
  v.ids = &host[0].id;
  v.ids_stride = sizeof(HostParticle);
  e.compute(v, strided);
  std::reverse(host.begin(), host.end());  // a neighbour-list rebuild reorders them
  e.compute(v, reordered);
  for (std::size_t c = 0; c < strided.size(); ++c) EXPECT_NEAR(strided[c], reordered[c], 1e-15 * p.volume());
  // Without ids the rotation follows the index: the packed SoA compute of the same order.
  // Bitwise equality needs the fixed summation order; threads otherwise add in any order.
  e.configure("deterministic=1");
  v.ids = nullptr;
  std::reverse(host.begin(), host.end());
  e.compute(v, strided);
  e.compute(p.view(), packed);
  EXPECT_EQ(strided, packed);
}

TEST(Coupling, LogCallbackReceivesTheEnginesMessages) {
  struct Seen {
    int count = 0;
    int level = -1;
  } seen;
  Engine e(grid(1, 2, 2, 2));
  e.set_log_callback(
      [](int level, const char* message, void* user) {
        auto* s = static_cast<Seen*>(user);
        ++s->count;
        s->level = level;
        EXPECT_NE(std::string(message).find("computed"), std::string::npos) << message;
      },
      &seen);
  e.configure("log_level=info method=direct");
  Particles p;
  p.add(0.5, 0.5, 0.5, 0.1);
  std::vector<double> out(e.cell_count());
  e.compute(p.view(), out);
  EXPECT_EQ(seen.count, 1);
  EXPECT_EQ(seen.level, 2);  // info
  e.set_log_callback(nullptr, nullptr);
  e.compute(p.view(), out);
  EXPECT_EQ(seen.count, 1);
}

}  // namespace
}  // namespace vfe::test

namespace vfe::test {
namespace {

// smoothing_length diffuses the solid volume over the face graph: conserved to round-off,
// never negative, flatter (a lower maximum), and nothing for a length of zero.
TEST(Smoothing, ConservesAndFlattensOnEveryMeshKind) {
  std::vector<std::unique_ptr<Engine>> engines;
  engines.push_back(std::make_unique<Engine>(grid(0.001, 20, 20, 20)));
  std::vector<double> x(21);
  for (int i = 0; i <= 20; ++i) x[i] = 0.02 * std::pow(i / 20.0, 1.2);
  engines.push_back(std::make_unique<Engine>(RectilinearGridSpec{{x, x, x}}));
  engines.push_back(std::make_unique<Engine>(PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"}));
  const Particles p = random_spheres(12, 300, 0.006, 0.014, 0.0003, 0.0006);
  for (auto& e : engines) {
    SCOPED_TRACE(e->cell_count());
    const std::vector<double> raw = run(*e, p, "method=pmm particle_grid=40 smoothing_length=0");
    for (const char* periodic : {"none", "xyz"}) {
      if (std::string(periodic) == "xyz" && e->cell_count() == 1920) continue;  // a polyMesh has no periodic axes
      const std::vector<double> smooth =
          run(*e, p, std::string("smoothing_length=0.002 periodic=") + periodic);
      EXPECT_NEAR(std::accumulate(smooth.begin(), smooth.end(), 0.0), p.volume(), 1e-12 * p.volume());
      EXPECT_GE(*std::min_element(smooth.begin(), smooth.end()), -1e-15 * p.volume());
      EXPECT_LT(*std::max_element(smooth.begin(), smooth.end()), 0.8 * *std::max_element(raw.begin(), raw.end()));
    }
    e->configure("periodic=none");
  }
}

}  // namespace
}  // namespace vfe::test

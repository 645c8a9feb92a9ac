// libvfe_mpi against the serial engine on the undecomposed grid: every method, slabs, pencils
// and 2x2x1 blocks, periodic and bounded axes, packed bed, dilute stream and particles
// larger than the cells. Run under mpirun with 1 to 4 ranks; every check is collective (the
// compared figure is reduced over ranks first, so all ranks pass or fail together).
#include <vfe/vfe_mpi.h>

#include <gtest/gtest.h>

#include "mpi_test.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace {

int g_rank = 0, g_size = 1;

struct Grid {
  std::array<double, 3> origin{-0.002, 0.001, 0.0};
  std::array<double, 3> spacing{0.001, 0.0011, 0.0009};  // anisotropic: ghost widths differ per axis
  std::array<int64_t, 3> cells{13, 10, 9};               // 13 and 9 do not split evenly
};

// n spheres of radius r_lo..r_hi with centres uniform in the box [lo, hi) (fractions of the
// grid per axis); ids are not the indices, so a rotation by index would differ.
Scene make_scene(const std::string& name, const Grid& g, int n, double r_lo, double r_hi, std::array<double, 3> lo,
                 std::array<double, 3> hi, unsigned seed) {
  Scene s;
  s.name = name;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < 3; ++d) {
      const double length = g.spacing[d] * double(g.cells[d]);
      s.centres.push_back(g.origin[d] + length * (lo[d] + (hi[d] - lo[d]) * u(rng)));
    }
    s.radii.push_back(r_lo + (r_hi - r_lo) * u(rng));
    s.ids.push_back(7919 * int64_t(i) + 12345);
  }
  return s;
}

std::vector<Scene> scenes(const Grid& g) {
  return {make_scene("packed bed", g, 700, 0.00045, 0.00055, {0, 0, 0}, {1, 1, 0.8}, 1),
          make_scene("dilute stream", g, 40, 0.0002, 0.0003, {0.4, 0.3, 0}, {0.6, 0.5, 1}, 2),
          make_scene("large particles", g, 12, 0.0012, 0.0019, {0, 0, 0}, {1, 1, 1}, 3)};
}

const char* const kMethods[] = {"direct",      "pmm",          "exact",     "divided", "gaussian",
                                "porous_cube", "big_particle", "trilinear", "auto"};

// Blocks of a px x py x pz split (uneven where the cells do not divide), rank r's block.
void split(const Grid& g, std::array<int, 3> parts, int rank, int64_t lo[3], int64_t hi[3]) {
  const int idx[3] = {rank % parts[0], (rank / parts[0]) % parts[1], rank / (parts[0] * parts[1])};
  for (int d = 0; d < 3; ++d) {
    lo[d] = g.cells[d] * idx[d] / parts[d];
    hi[d] = g.cells[d] * (idx[d] + 1) / parts[d];
  }
}

// The decompositions of g_size ranks exercised: slabs along x and z, pencils, 2x2x1.
std::vector<std::array<int, 3>> decompositions() {
  const int p = g_size;
  std::vector<std::array<int, 3>> d = {{p, 1, 1}};
  if (p > 1) d.push_back({1, 1, p});
  if (p == 4) {
    d.push_back({2, 2, 1});
    d.push_back({1, 2, 2});
  }
  if (p == 3) d.push_back({1, 3, 1});
  return d;
}

struct Local {
  std::vector<double> centres, radii;
  std::vector<int64_t> ids;
  std::vector<std::size_t> index;  // into the scene
};

// This rank's particles, chosen independently of the library: the cell of the centre.
Local owned_particles(const Scene& s, const Grid& g, const int64_t lo[3], const int64_t hi[3]) {
  Local l;
  for (std::size_t i = 0; i < s.size(); ++i) {
    bool mine = true;
    for (int d = 0; d < 3; ++d) {
      const int64_t c = int64_t(std::floor((s.centres[3 * i + d] - g.origin[d]) / g.spacing[d]));
      mine = mine && c >= lo[d] && c < hi[d];
    }
    if (!mine) continue;
    l.centres.insert(l.centres.end(), &s.centres[3 * i], &s.centres[3 * i + 3]);
    l.radii.push_back(s.radii[i]);
    l.ids.push_back(s.ids[i]);
    l.index.push_back(i);
  }
  return l;
}

// The serial engine's field on the whole grid, computed on rank 0 and sent to every rank.
std::vector<double> serial_field(const Grid& g, const Scene& s, const std::string& options) {
  std::vector<double> field(size_t(g.cells[0] * g.cells[1] * g.cells[2]));
  int ok = 1;
  if (g_rank == 0) {
    vfe_engine* e = nullptr;
    ok = vfe_create_cartesian(g.origin.data(), g.spacing.data(), g.cells.data(), &e) == VFE_OK &&
         vfe_configure(e, options.c_str()) == VFE_OK;
    const vfe_particles p = view(s.centres.data(), s.radii.data(), s.ids.data(), int64_t(s.size()));
    ok = ok && vfe_compute_particles(e, &p, field.data()) == VFE_OK;
    if (!ok) ADD_FAILURE() << "serial engine: " << vfe_last_error(e);
    vfe_destroy(e);
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Bcast(field.data(), int(field.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return field;
}


struct Comparison {
  double max_diff = 0;       // largest |distributed - serial| over owned cells of all ranks
  int64_t unequal_cells = 0; // cells not bitwise equal
};

// Owned cells of a distributed field against the serial field.
Comparison compare(const Grid& g, const std::vector<double>& owned, const std::vector<double>& serial,
                   const int64_t lo[3], const int64_t hi[3]) {
  Comparison c;
  std::size_t at = 0;
  for (int64_t k = lo[2]; k < hi[2]; ++k)
    for (int64_t j = lo[1]; j < hi[1]; ++j)
      for (int64_t i = lo[0]; i < hi[0]; ++i, ++at) {
        const double s = serial[size_t(i + g.cells[0] * (j + g.cells[1] * k))];
        c.max_diff = std::max(c.max_diff, std::abs(owned[at] - s));
        c.unequal_cells += owned[at] != s;
      }
  c.max_diff = max_over_ranks(c.max_diff);
  int64_t total = 0;
  MPI_Allreduce(&c.unequal_cells, &total, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  c.unequal_cells = total;
  return c;
}

vfe_engine* create(const Grid& g, const int64_t lo[3], const int64_t hi[3]) {
  vfe_engine* e = nullptr;
  const vfe_status s =
      vfe_mpi_create_cartesian(MPI_COMM_WORLD, g.origin.data(), g.spacing.data(), g.cells.data(), lo, hi, &e);
  EXPECT_EQ(s, VFE_OK) << vfe_last_error(nullptr);
  return e;
}

// This rank's block of a `parts` split, and a distributed engine on it with `options`.
vfe_engine* create_configured(const Grid& g, std::array<int, 3> parts, const std::string& options, int64_t lo[3],
                              int64_t hi[3]) {
  split(g, parts, g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  if (e) {
    EXPECT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
  }
  return e;
}

std::string describe(std::array<int, 3> parts) {
  return std::to_string(parts[0]) + "x" + std::to_string(parts[1]) + "x" + std::to_string(parts[2]);
}

// Every method, scene, decomposition and periodicity: owned-cell fields equal the serial
// engine's to 1e-12 of the particle volume per cell, and bitwise with deterministic=1.
TEST(DistributedCartesian, EqualsSerialEngineForEveryMethodAndDecomposition) {
  const Grid g;
  const std::vector<Scene> all = scenes(g);
  const char* const periodics[] = {"none", "xy", "xyz"};
  for (const char* deterministic : {"0", "1"})
  for (const char* periodic : periodics)
    for (const Scene& scene : all)
      for (const char* method : kMethods) {
        const std::string options = std::string("method=") + method + " periodic=" + periodic +
                                    " deterministic=" + deterministic + (deterministic[0] == '1' ? "" : " threads=1");
        const std::vector<double> serial = serial_field(g, scene, options);
        for (const std::array<int, 3>& parts : decompositions()) {
          int64_t lo[3], hi[3];
          split(g, parts, g_rank, lo, hi);
          vfe_engine* e = create(g, lo, hi);
          ASSERT_NE(e, nullptr);
          ASSERT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
          const Local l = owned_particles(scene, g, lo, hi);
          const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
          std::vector<double> owned(size_t(vfe_cell_count(e)), -1.0);
          ASSERT_EQ(vfe_compute_particles(e, &p, owned.data()), VFE_OK)
              << vfe_last_error(e) << " (" << scene.name << ", " << options << ", blocks " << describe(parts) << ")";
          const Comparison c = compare(g, owned, serial, lo, hi);
          EXPECT_LE(c.max_diff, 1e-12 * scene.largest_volume())
              << scene.name << ", " << options << ", blocks " << describe(parts);
          if (deterministic[0] == '1') {  // fixed-point sums: the serial field bit for bit
            EXPECT_EQ(c.unequal_cells, 0) << scene.name << ", " << options << ", blocks " << describe(parts);
          }
          vfe_report r{};
          ASSERT_EQ(vfe_last_report(e, &r), VFE_OK);
          EXPECT_EQ(r.particles, int64_t(scene.size())) << scene.name << ", " << options;
          vfe_destroy(e);
        }
      }
}

// deterministic=1 with two threads per rank, periodic walls between ranks and a rank its own
// neighbour: the owner adds its neighbours' fixed-point sums, so every owned cell equals the
// serial engine's bit for bit. The test prints the figure the closing note quotes.
TEST(DistributedCartesian, DeterministicIsBitwiseTheSerialField) {
  const Grid g;
  for (const Scene& scene : scenes(g))
    for (const char* periodic : {"none", "xy", "xyz"}) {
      const std::string options = std::string("method=pmm deterministic=1 threads=2 periodic=") + periodic;
      const std::vector<double> serial = serial_field(g, scene, options);
      for (const std::array<int, 3>& parts : decompositions()) {
        int64_t lo[3], hi[3];
        vfe_engine* e = create_configured(g, parts, options, lo, hi);
        ASSERT_NE(e, nullptr);
        const Local l = owned_particles(scene, g, lo, hi);
        const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
        std::vector<double> owned(size_t(vfe_cell_count(e)));
        ASSERT_EQ(vfe_compute_particles(e, &p, owned.data()), VFE_OK);
        const Comparison c = compare(g, owned, serial, lo, hi);
        if (g_rank == 0)
          std::printf("deterministic=1 %s periodic=%s, %d ranks, blocks %s: max |distributed - serial| = %.3g, "
                      "%lld of %lld cells not bitwise equal\n",
                      scene.name.c_str(), periodic, g_size, describe(parts).c_str(), c.max_diff,
                      static_cast<long long>(c.unequal_cells), static_cast<long long>(serial.size()));
        EXPECT_EQ(c.unequal_cells, 0) << scene.name << ", periodic " << periodic << ", blocks " << describe(parts);
        vfe_destroy(e);
      }
    }
}

// A compute with larger particles than the last widens the ghost layer on every rank.
TEST(DistributedCartesian, GhostLayerWidensForLargerParticles) {
  const Grid g;
  const std::vector<Scene> all = scenes(g);
  int64_t lo[3], hi[3];
  split(g, decompositions().back(), g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  ASSERT_EQ(vfe_configure(e, "method=exact periodic=x"), VFE_OK);
  double widths[2];
  for (int pass = 0; pass < 2; ++pass) {
    const Scene& scene = all[pass == 0 ? 1 : 2];  // stream, then large particles
    const std::vector<double> serial = serial_field(g, scene, "method=exact periodic=x");
    const Local l = owned_particles(scene, g, lo, hi);
    std::vector<double> owned(size_t(vfe_cell_count(e)));
    ASSERT_EQ(vfe_compute(e, int64_t(l.radii.size()), l.centres.data(), l.radii.data(), nullptr, owned.data()),
              VFE_OK)
        << vfe_last_error(e);
    EXPECT_LE(compare(g, owned, serial, lo, hi).max_diff, 1e-12 * scene.largest_volume());
    ASSERT_EQ(vfe_last_report_value(e, "ghost_width", &widths[pass]), VFE_OK);
  }
  // exact reaches r: ceil(r_max / h) + 1 cells on the finest axis (z, 0.9 mm), for the stream's
  // r_max < 0.3 mm 2 cells, then the large particles' width.
  const double r_large = *std::max_element(all[2].radii.begin(), all[2].radii.end());
  EXPECT_EQ(widths[0], 2);
  EXPECT_EQ(widths[1], std::ceil(r_large / g.spacing[2]) + 1);
  EXPECT_GT(widths[1], widths[0]);
  vfe_destroy(e);
}

// A particle on a rank that does not own its centre's cell fails the ordinary vfe_compute on
// every rank with the same status and rank 0's message, and leaves the outputs untouched.
TEST(DistributedCartesian, ParticleOnTheWrongRankIsRefusedEverywhere) {
  const Grid g;
  int64_t lo[3], hi[3];
  vfe_engine* e = create_configured(g, {g_size, 1, 1}, "method=exact", lo, hi);
  ASSERT_NE(e, nullptr);
  // Rank 0 passes a particle in the last cell along x (owned by the last rank); with one rank
  // every particle is its own, so it passes none and the compute succeeds.
  double centre[3] = {g.origin[0] + (double(g.cells[0]) - 0.5) * g.spacing[0], g.origin[1] + 0.005, g.origin[2] + 0.004};
  const double radius = 0.0004;
  int owner = -1;
  ASSERT_EQ(vfe_mpi_owner(e, centre, &owner), VFE_OK);
  EXPECT_EQ(owner, g_size - 1);
  const bool give = g_rank == 0 && g_size > 1;
  std::vector<double> owned(size_t(vfe_cell_count(e)), -7.0);
  const vfe_status s = vfe_compute(e, give ? 1 : 0, centre, &radius, nullptr, owned.data());
  if (g_size > 1) {
    EXPECT_EQ(s, VFE_ERROR_INVALID_ARGUMENT);
    const std::string message = vfe_last_error(e);
    EXPECT_EQ(message.rfind("rank 0: particle 0", 0), 0u) << message;
    EXPECT_NE(message.find("owned by rank " + std::to_string(g_size - 1)), std::string::npos) << message;
    EXPECT_TRUE(std::all_of(owned.begin(), owned.end(), [](double v) { return v == -7.0; }));
  } else {
    EXPECT_EQ(s, VFE_OK);
  }
  // The engine stays usable.
  EXPECT_EQ(vfe_compute(e, give ? 1 : 0, centre, &radius, nullptr, owned.data()) == VFE_OK, g_size == 1);
  EXPECT_EQ(vfe_compute(e, 0, nullptr, nullptr, nullptr, owned.data()), VFE_OK) << vfe_last_error(e);
  EXPECT_STREQ(vfe_last_error(e), "");
  vfe_destroy(e);
}

// A bad argument on one rank only (its solid_volume NULL) fails the collective call on every
// rank instead of leaving the others waiting in it; the next call works everywhere.
TEST(DistributedCartesian, NullArgumentOnOneRankFailsEveryRank) {
  const Grid g;
  int64_t lo[3], hi[3];
  split(g, {g_size, 1, 1}, g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  std::vector<double> owned(size_t(vfe_cell_count(e)), -7.0);
  const int last = g_size - 1;
  EXPECT_EQ(vfe_compute(e, 0, nullptr, nullptr, nullptr, g_rank == last ? nullptr : owned.data()),
            VFE_ERROR_INVALID_ARGUMENT);
  const std::string expected = (g_size > 1 ? "rank " + std::to_string(last) + ": " : std::string()) + "solid_volume is NULL";
  EXPECT_EQ(std::string(vfe_last_error(e)).rfind(expected, 0), 0u) << vfe_last_error(e);
  EXPECT_TRUE(std::all_of(owned.begin(), owned.end(), [](double v) { return v == -7.0; }));
  EXPECT_EQ(vfe_configure(e, g_rank == last ? nullptr : "method=direct"), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::strstr(vfe_last_error(e), "options is NULL"), nullptr) << vfe_last_error(e);
  EXPECT_EQ(vfe_compute(e, 0, nullptr, nullptr, nullptr, owned.data()), VFE_OK) << vfe_last_error(e);
  vfe_destroy(e);
}

// The MPI-only calls refuse an engine on one mesh with a message, leaving it and the
// outputs untouched; libvfe's own engines have no backend.
TEST(DistributedCartesian, EngineOfOneMeshIsNotDistributed) {
  const Grid g;
  vfe_engine* serial = nullptr;
  ASSERT_EQ(vfe_create_cartesian(g.origin.data(), g.spacing.data(), g.cells.data(), &serial), VFE_OK);
  const double centre[3] = {g.origin[0] + 0.0005, g.origin[1] + 0.0005, g.origin[2] + 0.0005}, radius = 0.0003;
  const int64_t id = 3;
  int owner = -5;
  EXPECT_EQ(vfe_mpi_owner(serial, centre, &owner), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(owner, -5);
  EXPECT_NE(std::strstr(vfe_last_error(serial), "vfe_mpi_owner: the engine is not distributed"), nullptr)
      << vfe_last_error(serial);
  int64_t got = -1;
  double *c = nullptr, *r = nullptr;
  int64_t* ids = nullptr;
  EXPECT_EQ(vfe_mpi_route_particles(serial, 1, centre, &radius, &id, &got, &c, &r, &ids), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(got, -1);
  EXPECT_EQ(c, nullptr);
  EXPECT_NE(std::strstr(vfe_last_error(serial), "not distributed"), nullptr) << vfe_last_error(serial);
  EXPECT_EQ(vfe_mpi_owner(nullptr, centre, &owner), VFE_ERROR_INVALID_ARGUMENT);
  // The engine stays usable.
  std::vector<double> solid(size_t(vfe_cell_count(serial)));
  EXPECT_EQ(vfe_compute(serial, 1, centre, &radius, nullptr, solid.data()), VFE_OK) << vfe_last_error(serial);
  vfe_destroy(serial);
}

// Shapes on a distributed engine: vfe_add_shape on every rank, pmm and direct on ellipsoids and
// clumps larger than the cells (ghost layer from the shapes' reach) equal the serial engine's.
// A spec refused on one rank only registers the shape on no rank, so ids stay equal.
TEST(DistributedCartesian, ShapesEqualSerialEngine) {
  const Grid g;
  const Scene scene = scenes(g)[2];  // 12 particles of scale 1.2 to 1.9 mm: wider than the cells
  const char* const specs[] = {"ellipsoid 1.2 0.6 0.5", "clump 0 0 0 0.7; 0.6 0.2 0 0.5"};
  std::vector<int32_t> shape_ids(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i) shape_ids[i] = int32_t(i % 2);
  // pmm with particle_grid=auto sizes a shape's template per compute (per rank): refused.
  for (const char* method : {"pmm particle_grid=2000", "direct", "direct deterministic=1"}) {
    const std::string options = std::string("method=") + method + " periodic=x threads=1";
    std::vector<double> serial(size_t(g.cells[0] * g.cells[1] * g.cells[2]));
    {
      vfe_engine* s = nullptr;
      ASSERT_EQ(vfe_create_cartesian(g.origin.data(), g.spacing.data(), g.cells.data(), &s), VFE_OK);
      ASSERT_EQ(vfe_configure(s, options.c_str()), VFE_OK);
      int32_t id = -1;
      for (const char* spec : specs) ASSERT_EQ(vfe_add_shape(s, spec, &id), VFE_OK) << vfe_last_error(s);
      vfe_particles p = view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size()));
      p.shape_ids = shape_ids.data();
      ASSERT_EQ(vfe_compute_particles(s, &p, serial.data()), VFE_OK) << vfe_last_error(s);
      vfe_destroy(s);
    }
    {  // one decomposition: the shapes' templates are costly to build on every engine
      const std::array<int, 3> parts = decompositions().back();
      int64_t lo[3], hi[3];
      split(g, parts, g_rank, lo, hi);
      vfe_engine* e = create(g, lo, hi);
      ASSERT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
      int32_t id = -1;
      // The last rank's spec is bad: every rank fails, none registers it.
      EXPECT_EQ(vfe_add_shape(e, g_rank == g_size - 1 ? "ellipsoid 1 1 -1" : specs[0], &id), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_EQ(id, -1);
      for (int32_t k = 0; k < 2; ++k) {
        ASSERT_EQ(vfe_add_shape(e, specs[k], &id), VFE_OK) << vfe_last_error(e);
        EXPECT_EQ(id, k);
      }
      Local l = owned_particles(scene, g, lo, hi);
      std::vector<int32_t> my_shapes;
      for (const std::size_t i : l.index) my_shapes.push_back(shape_ids[i]);
      vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
      p.shape_ids = my_shapes.data();
      std::vector<double> owned(size_t(vfe_cell_count(e)));
      ASSERT_EQ(vfe_compute_particles(e, &p, owned.data()), VFE_OK) << vfe_last_error(e);
      const Comparison c = compare(g, owned, serial, lo, hi);
      EXPECT_LE(c.max_diff, 1e-12 * scene.largest_volume()) << method << ", blocks " << describe(parts);
      if (std::strstr(method, "deterministic=1")) {  // one fixed-point unit from the shapes' volumes on every rank
        EXPECT_EQ(c.unequal_cells, 0) << method << ", blocks " << describe(parts);
      }
      vfe_report r{};
      ASSERT_EQ(vfe_last_report(e, &r), VFE_OK);
      EXPECT_EQ(r.particles, int64_t(scene.size()));
      vfe_destroy(e);
    }
  }
}

TEST(DistributedCartesian, RandomOrientationWithoutIdsIsRefused) {
  const Grid g;
  int64_t lo[3], hi[3];
  split(g, {g_size, 1, 1}, g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  const Local l = owned_particles(scenes(g)[0], g, lo, hi);
  std::vector<double> owned(size_t(vfe_cell_count(e)));
  // Every rank owns some of the bed's particles, so every rank fails alike.
  EXPECT_EQ(vfe_compute(e, int64_t(l.radii.size()), l.centres.data(), l.radii.data(), nullptr, owned.data()),
            VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::strstr(vfe_last_error(e), "ids"), nullptr) << vfe_last_error(e);
  vfe_destroy(e);
}

TEST(DistributedCartesian, BlocksThatDoNotTileTheGridAreRefused) {
  const Grid g;
  int64_t lo[3] = {0, 0, 0}, hi[3] = {g.cells[0], g.cells[1], g.cells[2]};
  vfe_engine* e = nullptr;
  if (g_size > 1) {  // every rank claims the whole grid: overlap
    EXPECT_EQ(vfe_mpi_create_cartesian(MPI_COMM_WORLD, g.origin.data(), g.spacing.data(), g.cells.data(), lo, hi, &e),
              VFE_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::strstr(vfe_last_error(nullptr), "overlap"), nullptr) << vfe_last_error(nullptr);
  }
  hi[0] = g.cells[0] - 1;  // a gap (and overlaps with more ranks)
  EXPECT_EQ(vfe_mpi_create_cartesian(MPI_COMM_WORLD, g.origin.data(), g.spacing.data(), g.cells.data(), lo, hi, &e),
            VFE_ERROR_INVALID_ARGUMENT);
  const double bad_spacing[3] = {0.001, 0, 0.001};
  split(g, {g_size, 1, 1}, g_rank, lo, hi);
  EXPECT_EQ(vfe_mpi_create_cartesian(MPI_COMM_WORLD, g.origin.data(), bad_spacing, g.cells.data(), lo, hi, &e),
            VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(e, nullptr);
}

TEST(DistributedCartesian, BadOptionChangesNothing) {
  const Grid g;
  int64_t lo[3], hi[3];
  split(g, {g_size, 1, 1}, g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  ASSERT_EQ(vfe_configure(e, "method=exact"), VFE_OK);
  EXPECT_EQ(vfe_configure(e, "method=direct periodic=w"), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(vfe_configure(e, "method=direct sigma=-1"), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(vfe_configure(e, "method=direct smoothing_length=0.001"), VFE_ERROR_UNSUPPORTED);
  EXPECT_NE(std::strstr(vfe_last_error(e), "smoothing_length"), nullptr) << vfe_last_error(e);
  const Scene scene = scenes(g)[2];
  const std::vector<double> serial = serial_field(g, scene, "method=exact");
  const Local l = owned_particles(scene, g, lo, hi);
  std::vector<double> owned(size_t(vfe_cell_count(e)));
  ASSERT_EQ(vfe_compute(e, int64_t(l.radii.size()), l.centres.data(), l.radii.data(), nullptr, owned.data()),
            VFE_OK);
  EXPECT_LE(compare(g, owned, serial, lo, hi).max_diff, 1e-12 * scene.largest_volume());
  vfe_destroy(e);
}

// deposit (reverse halo sum of k components) and interpolate (forward halo fill) against the
// serial engine's with weights=1; the void fraction against 1 - Vs/V of the serial field.
// With deterministic=1 each of them is the serial one bit for bit.
void check_deposit_interpolate_void_fraction(bool deterministic) {
  const Grid g;
  const Scene scene = scenes(g)[0];
  const std::string options =
      std::string("method=gaussian periodic=xz weights=1 alpha_min=0.3") + (deterministic ? " deterministic=1" : "");
  const int k = 2;
  std::vector<double> values(2 * scene.size()), field(size_t(2 * g.cells[0] * g.cells[1] * g.cells[2]));
  for (std::size_t i = 0; i < scene.size(); ++i) {
    values[2 * i] = double(scene.ids[i] % 17);
    values[2 * i + 1] = -scene.radii[i];
  }
  for (std::size_t c = 0; c < field.size(); ++c) field[c] = std::sin(0.37 * double(c));
  std::vector<double> serial_deposit(field.size()), serial_interp(2 * scene.size()), serial_eps(field.size() / 2);
  std::vector<int64_t> serial_offsets, serial_cells;
  std::vector<double> serial_fractions;
  {
    vfe_engine* s = nullptr;
    ASSERT_EQ(vfe_create_cartesian(g.origin.data(), g.spacing.data(), g.cells.data(), &s), VFE_OK);
    ASSERT_EQ(vfe_configure(s, options.c_str()), VFE_OK);
    const vfe_particles p = view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size()));
    std::vector<double> solid(serial_eps.size());
    ASSERT_EQ(vfe_compute_particles(s, &p, solid.data()), VFE_OK);
    ASSERT_EQ(vfe_deposit(s, k, values.data(), serial_deposit.data()), VFE_OK);
    ASSERT_EQ(vfe_interpolate(s, k, field.data(), serial_interp.data()), VFE_OK);
    ASSERT_EQ(vfe_void_fraction(s, serial_eps.data()), VFE_OK);
    int64_t np = 0, ne = 0;
    ASSERT_EQ(vfe_weights_size(s, &np, &ne), VFE_OK);
    serial_offsets.resize(size_t(np + 1));
    serial_cells.resize(size_t(ne));
    serial_fractions.resize(size_t(ne));
    ASSERT_EQ(vfe_weights(s, serial_offsets.data(), serial_cells.data(), serial_fractions.data()), VFE_OK);
    vfe_destroy(s);
  }
  for (const std::array<int, 3>& parts : decompositions()) {
    int64_t lo[3], hi[3];
    vfe_engine* e = create_configured(g, parts, options, lo, hi);
    ASSERT_NE(e, nullptr);
    const Local l = owned_particles(scene, g, lo, hi);
    const std::size_t n = l.radii.size(), cells = size_t(vfe_cell_count(e));
    const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(n));
    std::vector<double> solid(cells), eps(cells), my_values(2 * n), my_field(2 * cells), dep(2 * cells), interp(2 * n);
    ASSERT_EQ(vfe_compute_particles(e, &p, solid.data()), VFE_OK);
    ASSERT_EQ(vfe_void_fraction(e, eps.data()), VFE_OK);
    for (std::size_t i = 0; i < n; ++i)
      for (int j = 0; j < k; ++j) my_values[2 * i + j] = values[2 * l.index[i] + j];
    std::size_t at = 0;
    for (int64_t z = lo[2]; z < hi[2]; ++z)
      for (int64_t y = lo[1]; y < hi[1]; ++y)
        for (int64_t x = lo[0]; x < hi[0]; ++x, ++at)
          for (int j = 0; j < k; ++j) my_field[2 * at + j] = field[2 * size_t(x + g.cells[0] * (y + g.cells[1] * z)) + j];
    ASSERT_EQ(vfe_deposit(e, k, my_values.data(), dep.data()), VFE_OK) << vfe_last_error(e);
    ASSERT_EQ(vfe_interpolate(e, k, my_field.data(), interp.data()), VFE_OK) << vfe_last_error(e);
    // Component j of each owned cell against the serial field's.
    for (int j = 0; j < k; ++j) {
      std::vector<double> mine(cells), theirs(serial_eps.size());
      for (std::size_t c = 0; c < cells; ++c) mine[c] = dep[2 * c + j];
      for (std::size_t c = 0; c < theirs.size(); ++c) theirs[c] = serial_deposit[2 * c + j];
      const Comparison c = compare(g, mine, theirs, lo, hi);
      EXPECT_LE(c.max_diff, 1e-12 * 17) << "deposit component " << j;
      if (deterministic) {
        EXPECT_EQ(c.unequal_cells, 0) << "deposit component " << j << ", blocks " << describe(parts);
      }
    }
    const Comparison ce = compare(g, eps, serial_eps, lo, hi);
    EXPECT_LE(ce.max_diff, 1e-12);
    if (deterministic) {
      EXPECT_EQ(ce.unequal_cells, 0) << "void fraction, blocks " << describe(parts);
    }
    double worst = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (int j = 0; j < k; ++j) worst = std::max(worst, std::abs(interp[2 * i + j] - serial_interp[2 * l.index[i] + j]));
    EXPECT_LE(max_over_ranks(worst), deterministic ? 0.0 : 1e-12) << "interpolate, blocks " << describe(parts);
    // Weights name global cells: each particle's (cell, fraction) list equals the serial one.
    int64_t np = 0, ne = 0;
    ASSERT_EQ(vfe_weights_size(e, &np, &ne), VFE_OK);
    ASSERT_EQ(np, int64_t(n));
    std::vector<int64_t> offsets(static_cast<size_t>(np + 1)), wcells(static_cast<size_t>(ne));
    std::vector<double> fractions(static_cast<size_t>(ne));
    ASSERT_EQ(vfe_weights(e, offsets.data(), wcells.data(), fractions.data()), VFE_OK);
    double weight_diff = 0;
    for (std::size_t i = 0; i < n; ++i) {
      std::vector<std::pair<int64_t, double>> mine, theirs;
      for (int64_t a = offsets[i]; a < offsets[i + 1]; ++a) mine.push_back({wcells[size_t(a)], fractions[size_t(a)]});
      const std::size_t q = l.index[i];
      for (int64_t a = serial_offsets[q]; a < serial_offsets[q + 1]; ++a)
        theirs.push_back({serial_cells[size_t(a)], serial_fractions[size_t(a)]});
      std::sort(mine.begin(), mine.end());
      std::sort(theirs.begin(), theirs.end());
      if (mine.size() != theirs.size()) weight_diff = 1;
      for (std::size_t a = 0; a < std::min(mine.size(), theirs.size()); ++a)
        weight_diff = std::max(weight_diff, mine[a].first != theirs[a].first ? 1.0 : std::abs(mine[a].second - theirs[a].second));
    }
    EXPECT_LE(max_over_ranks(weight_diff), 1e-12) << "weights, blocks " << describe(parts);
    vfe_destroy(e);
  }
}

TEST(DistributedCartesian, DepositInterpolateAndVoidFractionEqualSerial) { check_deposit_interpolate_void_fraction(false); }
TEST(DistributedCartesian, DeterministicDepositInterpolateAndVoidFractionAreBitwiseSerial) {
  check_deposit_interpolate_void_fraction(true);
}

// Particles all given on rank 0 reach their owners; computing there equals the serial engine.
TEST(DistributedCartesian, RoutedParticlesEqualSerial) {
  const Grid g;
  const Scene scene = scenes(g)[2];
  int64_t lo[3], hi[3];
  split(g, decompositions().back(), g_rank, lo, hi);
  vfe_engine* e = create(g, lo, hi);
  ASSERT_EQ(vfe_configure(e, "method=pmm periodic=y"), VFE_OK);
  const int64_t n = g_rank == 0 ? int64_t(scene.size()) : 0;
  int64_t got = 0;
  double *c = nullptr, *r = nullptr;
  int64_t* ids = nullptr;
  ASSERT_EQ(vfe_mpi_route_particles(e, n, scene.centres.data(), scene.radii.data(), scene.ids.data(), &got, &c, &r, &ids),
            VFE_OK)
      << vfe_last_error(e);
  EXPECT_EQ(got, int64_t(owned_particles(scene, g, lo, hi).radii.size()));
  std::vector<double> owned(size_t(vfe_cell_count(e)));
  const vfe_particles p = view(c, r, ids, got);
  ASSERT_EQ(vfe_compute_particles(e, &p, owned.data()), VFE_OK) << vfe_last_error(e);
  EXPECT_LE(compare(g, owned, serial_field(g, scene, "method=pmm periodic=y"), lo, hi).max_diff,
            1e-12 * scene.largest_volume());
  std::free(c);
  std::free(r);
  std::free(ids);
  vfe_destroy(e);
}

}  // namespace

int main(int argc, char** argv) { return mpi_gtest_main(argc, argv, g_rank, g_size); }

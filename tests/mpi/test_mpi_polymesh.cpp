// libvfe_mpi on OpenFOAM meshes split by decomposePar (method simple; the processor folders
// are committed under data/openfoam/decomposed, scripts/decompose_test_meshes.sh remakes
// them) against the serial engine on the undecomposed mesh: every polyMesh method, a bed,
// particles on the processor boundaries and particles larger than the cells. Run under
// mpirun with 1 to 4 ranks (1 rank takes the undecomposed case). Owned cells are mapped to
// the global mesh through cellProcAddressing, read here with libvfe's reader; each rank's
// particles are chosen from the serial engine's cell of each centre, not by libvfe_mpi.
#include <vfe/engine.hpp>
#include <vfe/vfe_mpi.h>

#include <gtest/gtest.h>

#include "mpi_test.hpp"

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace {

int g_rank = 0, g_size = 1;

const std::string kData = VFE_SOURCE_DIR "/data/openfoam/";

struct Mesh {
  std::string name;
  double lo[3], hi[3];  // where particle centres are drawn (m)
};

const Mesh kMeshes[] = {{"box_uniform_10x10x30", {0, 0, 0}, {0.02, 0.02, 0.06}},
                        {"cylinder_ogrid_coarse", {0, 0, 0}, {0.02, 0.02, 0.06}}};

std::string undecomposed(const Mesh& m) { return kData + m.name; }
std::string my_folder(const Mesh& m) {
  return g_size == 1 ? undecomposed(m)
                     : kData + "decomposed/" + m.name + "_" + std::to_string(g_size) + "/processor" + std::to_string(g_rank);
}

// Global cell of each local cell of this rank.
std::vector<int64_t> my_cell_ids(const Mesh& m) {
  if (g_size > 1) return vfe::read_polymesh_labels(my_folder(m), "cellProcAddressing");
  vfe::Engine e(vfe::PolyMeshSpec{undecomposed(m)});
  std::vector<int64_t> ids(static_cast<std::size_t>(e.cell_count()));
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = int64_t(i);
  return ids;
}

// n spheres, radii r_lo..r_hi, centres uniform in the mesh's box (fractions lo..hi per axis)
// and inside the mesh (the serial engine locates them); ids are not the indices.
Scene make_scene(const std::string& name, const Mesh& m, vfe::Engine& serial, int n, double r_lo, double r_hi,
                 std::array<double, 3> lo, std::array<double, 3> hi, unsigned seed) {
  Scene s;
  s.name = name;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  while (int(s.size()) < n) {
    double x[3];
    for (int d = 0; d < 3; ++d) x[d] = m.lo[d] + (m.hi[d] - m.lo[d]) * (lo[d] + (hi[d] - lo[d]) * u(rng));
    const double r = r_lo + (r_hi - r_lo) * u(rng);
    int64_t cell = -1;
    serial.locate({x, 3}, {&cell, 1});
    if (cell < 0) continue;
    s.centres.insert(s.centres.end(), x, x + 3);
    s.radii.push_back(r);
    s.ids.push_back(7919 * int64_t(s.size()) + 12345);
  }
  return s;
}

std::vector<Scene> scenes(const Mesh& m, vfe::Engine& serial) {
  return {make_scene("bed", m, serial, 100, 0.0008, 0.0011, {0, 0, 0}, {1, 1, 0.5}, 1),
          // A thin sheet across the middle of every axis: where the simple decompositions cut.
          make_scene("processor boundaries", m, serial, 30, 0.0005, 0.0012, {0.45, 0.45, 0.3}, {0.55, 0.55, 0.7}, 2),
          make_scene("larger than the cells", m, serial, 6, 0.003, 0.0045, {0, 0, 0}, {1, 1, 1}, 3)};
}

struct Local {
  std::vector<double> centres, radii;
  std::vector<int64_t> ids;
};

// This rank's particles: those whose centre the serial engine finds in one of its cells.
Local my_particles(const Scene& s, vfe::Engine& serial, const std::vector<int64_t>& cell_ids) {
  std::vector<int64_t> cells(s.size());
  serial.locate(s.centres, cells);
  std::vector<char> mine(static_cast<std::size_t>(serial.cell_count()), 0);
  for (int64_t c : cell_ids) mine[static_cast<std::size_t>(c)] = 1;
  Local l;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (mine[static_cast<std::size_t>(cells[i])]) {
      l.centres.insert(l.centres.end(), &s.centres[3 * i], &s.centres[3 * i + 3]);
      l.radii.push_back(s.radii[i]);
      l.ids.push_back(s.ids[i]);
    }
  return l;
}

double sum_over_ranks(double v) {
  double m = 0;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return m;
}

// Largest |distributed - serial| over the owned cells of every rank (global cells via ids).
double max_difference(const std::vector<double>& owned, const std::vector<int64_t>& cell_ids,
                      const std::vector<double>& serial) {
  double worst = 0;
  for (std::size_t c = 0; c < owned.size(); ++c)
    worst = std::max(worst, std::abs(owned[c] - serial[static_cast<std::size_t>(cell_ids[c])]));
  return max_over_ranks(worst);
}

// Owned cells, over all ranks, whose value is not the serial one bit for bit.
double unequal_cells(const std::vector<double>& owned, const std::vector<int64_t>& cell_ids,
                     const std::vector<double>& serial) {
  double count = 0;
  for (std::size_t c = 0; c < owned.size(); ++c) count += owned[c] != serial[static_cast<std::size_t>(cell_ids[c])];
  return sum_over_ranks(count);
}

const char* const kMethods[] = {"direct", "pmm", "exact", "divided", "big_particle", "gaussian", "porous_cube", "auto"};

TEST(DistributedPolyMesh, EqualsSerialEngineForEveryMethod) {
  for (const Mesh& mesh : kMeshes) {
    vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
    const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
    // Every global cell is owned by exactly one rank.
    ASSERT_EQ(sum_over_ranks(double(cell_ids.size())), double(serial.cell_count())) << mesh.name;
    vfe_engine* e = nullptr;
    ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
    ASSERT_EQ(vfe_cell_count(e), int64_t(cell_ids.size()));
    for (const Scene& scene : scenes(mesh, serial)) {
      const Local l = my_particles(scene, serial, cell_ids);
      ASSERT_EQ(sum_over_ranks(double(l.radii.size())), double(scene.size()));
      for (const char* method : kMethods)
      for (const char* deterministic : {"0", "1"}) {
        const std::string options = std::string("method=") + method + " deterministic=" + deterministic;
        serial.configure(options);
        std::vector<double> expected(static_cast<std::size_t>(serial.cell_count()));
        serial.compute(view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size())), expected);
        ASSERT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
        std::vector<double> field(cell_ids.size(), -1.0);
        const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
        ASSERT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
        const double diff = max_difference(field, cell_ids, expected);
        EXPECT_LE(diff, 1e-12 * scene.largest_volume())
            << mesh.name << ", " << scene.name << ", " << method << " on " << g_size << " ranks";
        double total = 0;
        for (double v : field) total += v;
        EXPECT_NEAR(sum_over_ranks(total), scene.volume(), 1e-12 * scene.volume())
            << mesh.name << ", " << scene.name << ", " << method << ": volume not conserved";
        const double unequal = unequal_cells(field, cell_ids, expected);
        // deterministic=1 sums in fixed point, so the methods whose deposits do not depend on
        // a cell's own geometry (point location, cell centres) are the serial field bit for
        // bit. exact, gaussian and porous_cube integrate over ghost cells rebuilt from the
        // neighbour's faces in another order, which rounds differently (docs/scaling.md), and
        // so does auto where it takes exact.
        const std::string m = method;
        if (deterministic[0] == '1' && m != "exact" && m != "gaussian" && m != "porous_cube" && m != "auto") {
          EXPECT_EQ(unequal, 0) << mesh.name << ", " << scene.name << ", " << method << " on " << g_size << " ranks";
        }
        if (g_rank == 0 && diff > 0)
          std::printf("[ polymesh ] %s %s %-12s deterministic=%s %d ranks: max diff %.1e of V_p, %.0f cells not "
                      "bitwise equal\n",
                      mesh.name.c_str(), scene.name.c_str(), method, deterministic, g_size,
                      diff / scene.largest_volume(), unequal);
      }
    }
    vfe_destroy(e);
  }
}

// Long ellipsoids across the processor boundaries (pmm and direct): the ghost layer from the
// shape's reach (4 x the scale), fields equal to the serial engine's on the undecomposed mesh;
// pmm's particle_grid=auto, which sizes a shape's template per compute, is refused.
TEST(DistributedPolyMesh, ShapesEqualSerialEngine) {
  const Mesh& mesh = kMeshes[0];
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  const char* const spec = "ellipsoid 4 0.7 0.6";
  ASSERT_EQ(serial.add_shape(spec), 0);
  vfe_engine* e = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
  int32_t id = -1;
  ASSERT_EQ(vfe_add_shape(e, spec, &id), VFE_OK) << vfe_last_error(e);
  ASSERT_EQ(id, 0);
  const Scene scene = scenes(mesh, serial)[1];
  const Local l = my_particles(scene, serial, cell_ids);
  const std::vector<int32_t> all_shapes(scene.size(), 0), my_shapes(l.radii.size(), 0);
  // pmm with particle_grid=auto sizes a shape's template per compute (per rank): refused.
  for (const char* method : {"pmm particle_grid=2000", "direct"}) {
    // outside=drop: no widening for the nearest cells, so the shape's reach alone sizes the layer.
    const std::string options = std::string("method=") + method + " outside=drop";
    serial.configure(options);
    std::vector<double> expected(static_cast<std::size_t>(serial.cell_count()));
    vfe_particles all = view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size()));
    all.shape_ids = all_shapes.data();
    serial.compute(all, expected);
    ASSERT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
    vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
    p.shape_ids = my_shapes.data();
    std::vector<double> field(cell_ids.size(), -1.0);
    ASSERT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
    EXPECT_LE(max_difference(field, cell_ids, expected), 1e-12 * scene.largest_volume()) << method;
  }
  ASSERT_EQ(vfe_configure(e, "method=pmm particle_grid=auto"), VFE_OK);
  vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
  p.shape_ids = my_shapes.data();
  std::vector<double> field(cell_ids.size(), -1.0);
  EXPECT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_ERROR_UNSUPPORTED);
  EXPECT_NE(std::string(vfe_last_error(e)).find("particle_grid=N"), std::string::npos) << vfe_last_error(e);
  vfe_destroy(e);
}

TEST(DistributedPolyMesh, GhostLayerWidensForLargerParticles) {
  for (const Mesh& mesh : kMeshes) {
    vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
    const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
    vfe_engine* e = nullptr;
    ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK)
        << vfe_last_error(nullptr);
    ASSERT_EQ(vfe_configure(e, "method=exact outside=drop"), VFE_OK) << vfe_last_error(e);
    double widths[2] = {0, 0}, bytes[2] = {0, 0};
    const std::vector<Scene> all = scenes(mesh, serial);
    for (int k = 0; k < 2; ++k) {
      const Scene& scene = all[k == 0 ? 1 : 2];
      const Local l = my_particles(scene, serial, cell_ids);
      std::vector<double> field(cell_ids.size());
      const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
      ASSERT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
      ASSERT_EQ(vfe_last_report_value(e, "ghost_width", &widths[k]), VFE_OK);
      ASSERT_EQ(vfe_last_report_value(e, "ghost_bytes", &bytes[k]), VFE_OK);
      double local_cells = 0;
      ASSERT_EQ(vfe_last_report_value(e, "local_cells", &local_cells), VFE_OK);
      const double most_ghosts = max_over_ranks(local_cells - double(cell_ids.size()));
      // exact reaches r; the layer adds one cell (the largest cell side, about 2.3 mm here).
      EXPECT_GE(widths[k], *std::max_element(scene.radii.begin(), scene.radii.end()));
      const double most = max_over_ranks(bytes[k]), owned = double(cell_ids.size());
      const double least_owned = -max_over_ranks(-owned), most_owned = max_over_ranks(owned);
      if (g_size > 1) {
        EXPECT_GT(most, 0);
      }
      if (g_rank == 0)
        std::printf("[ polymesh ] %s, %d ranks: ghost width %.4f m, ghost geometry received up to %.0f bytes per rank "
                    "for up to %.0f ghost cells (owned cells per rank %.0f to %.0f)\n",
                    mesh.name.c_str(), g_size, widths[k], most, most_ghosts, least_owned, most_owned);
    }
    EXPECT_GT(widths[1], widths[0]);
    vfe_destroy(e);
  }
}

// Rank owning each global cell, from every rank's cellProcAddressing.
std::vector<int> owner_ranks(const std::vector<int64_t>& cell_ids, int64_t global_cells) {
  std::vector<int> mine(static_cast<std::size_t>(global_cells), -1), owners(mine.size());
  for (int64_t c : cell_ids) mine[static_cast<std::size_t>(c)] = g_rank;
  MPI_Allreduce(mine.data(), owners.data(), int(mine.size()), MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return owners;
}

TEST(DistributedPolyMesh, CentresOutsideTheMeshBelongToTheNearestCellsOwner) {
  const Mesh& mesh = kMeshes[1];  // the cylinder: centres beyond its mantle, inside its box
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  const std::vector<int> owners = owner_ranks(cell_ids, serial.cell_count());
  std::vector<double> centres_of_cells(static_cast<std::size_t>(3 * serial.cell_count()));
  serial.cell_centres(centres_of_cells);
  // Spheres centred 0.2 to 1 mm outside the mantle (radius 10 mm about (10, 10) mm) at
  // several angles and heights, so that every rank's share of the wall gets some.
  Scene s;
  s.name = "outside";
  for (int i = 0; i < 12; ++i) {
    const double angle = 0.5 + 2 * M_PI * i / 12, radius = 0.0102 + 0.0008 * (i % 3) / 2;
    s.centres.insert(s.centres.end(), {0.01 + radius * std::cos(angle), 0.01 + radius * std::sin(angle), 0.004 + 0.0045 * i});
    s.radii.push_back(0.0009 + 0.0001 * (i % 4));
    s.ids.push_back(1000 + i);
  }
  Local l;
  for (std::size_t i = 0; i < s.size(); ++i) {
    int64_t cell = 0;
    serial.locate({&s.centres[3 * i], 3}, {&cell, 1});
    ASSERT_EQ(cell, -1) << "sphere " << i << " should be centred outside the mesh";
    // The owner by the rule in vfe_mpi.h: the cell whose centre is nearest.
    double best = 1e300;
    for (int64_t c = 0; c < serial.cell_count(); ++c) {
      double d2 = 0;
      for (int d = 0; d < 3; ++d) d2 += std::pow(s.centres[3 * i + d] - centres_of_cells[static_cast<std::size_t>(3 * c + d)], 2);
      if (d2 < best) {
        best = d2;
        cell = c;
      }
    }
    if (owners[static_cast<std::size_t>(cell)] != g_rank) continue;
    l.centres.insert(l.centres.end(), &s.centres[3 * i], &s.centres[3 * i + 3]);
    l.radii.push_back(s.radii[i]);
    l.ids.push_back(s.ids[i]);
  }
  vfe_engine* e = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
  for (const char* options : {"method=pmm outside=nearest", "method=exact outside=drop", "method=divided outside=centre"}) {
    serial.configure(options);
    std::vector<double> expected(static_cast<std::size_t>(serial.cell_count()));
    serial.compute(view(s.centres.data(), s.radii.data(), s.ids.data(), int64_t(s.size())), expected);
    ASSERT_EQ(vfe_configure(e, options), VFE_OK) << vfe_last_error(e);
    std::vector<double> field(cell_ids.size());
    const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
    ASSERT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
    EXPECT_LE(max_difference(field, cell_ids, expected), 1e-12 * s.largest_volume()) << options;
  }
  vfe_destroy(e);
}

TEST(DistributedPolyMesh, DepositInterpolateWeightsAndVoidFractionEqualSerial) {
  const Mesh& mesh = kMeshes[1];
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  const Scene scene = scenes(mesh, serial)[0];
  const Local l = my_particles(scene, serial, cell_ids);
  const std::string options = "method=exact weights=1 alpha_min=0.3";
  serial.configure(options);
  std::vector<double> expected(static_cast<std::size_t>(serial.cell_count()));
  serial.compute(view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size())), expected);
  vfe_engine* e = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
  ASSERT_EQ(vfe_configure(e, options.c_str()), VFE_OK) << vfe_last_error(e);
  const std::size_t n = cell_ids.size(), np = l.radii.size();
  std::vector<double> field(n);
  const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(np));
  ASSERT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
  // Void fraction with alpha_min.
  std::vector<double> eps_serial(expected.size()), eps(n);
  serial.void_fraction(eps_serial);
  ASSERT_EQ(vfe_void_fraction(e, eps.data()), VFE_OK);
  double worst = 0;
  for (std::size_t c = 0; c < n; ++c) worst = std::max(worst, std::abs(eps[c] - eps_serial[static_cast<std::size_t>(cell_ids[c])]));
  EXPECT_LE(max_over_ranks(worst), 1e-12);
  // Deposit of two values per particle (a function of its id), over all ranks.
  std::vector<double> values_all(2 * scene.size()), values(2 * np);
  for (std::size_t i = 0; i < scene.size(); ++i) values_all[2 * i] = 1.0 + 1e-3 * double(scene.ids[i] % 97), values_all[2 * i + 1] = -2.0;
  for (std::size_t i = 0; i < np; ++i) values[2 * i] = 1.0 + 1e-3 * double(l.ids[i] % 97), values[2 * i + 1] = -2.0;
  std::vector<double> dep_serial(2 * expected.size()), dep(2 * n);
  serial.deposit(2, values_all, dep_serial);
  ASSERT_EQ(vfe_deposit(e, 2, values.data(), dep.data()), VFE_OK) << vfe_last_error(e);
  worst = 0;
  for (std::size_t c = 0; c < n; ++c)
    for (int j = 0; j < 2; ++j)
      worst = std::max(worst, std::abs(dep[2 * c + j] - dep_serial[static_cast<std::size_t>(2 * cell_ids[c] + j)]));
  EXPECT_LE(max_over_ranks(worst), 2e-12);  // values up to 2: twice the bound on fractions
  // Interpolation of a cell field (a function of the global cell) needs the ghosts' values.
  std::vector<double> cell_field_all(expected.size()), cell_field(n);
  for (std::size_t c = 0; c < expected.size(); ++c) cell_field_all[c] = std::sin(0.01 * double(c));
  for (std::size_t c = 0; c < n; ++c) cell_field[c] = cell_field_all[static_cast<std::size_t>(cell_ids[c])];
  std::vector<double> at_serial(scene.size()), at(np);
  serial.interpolate(1, cell_field_all, at_serial);
  ASSERT_EQ(vfe_interpolate(e, 1, cell_field.data(), at.data()), VFE_OK) << vfe_last_error(e);
  worst = 0;
  for (std::size_t i = 0; i < np; ++i) {
    const std::size_t k = static_cast<std::size_t>(std::find(scene.ids.begin(), scene.ids.end(), l.ids[i]) - scene.ids.begin());
    worst = std::max(worst, std::abs(at[i] - at_serial[k]));
  }
  EXPECT_LE(max_over_ranks(worst), 1e-12);
  // Weights name global cells: each particle's fractions per global cell match the serial ones.
  int64_t particles = 0, entries = 0;
  ASSERT_EQ(vfe_weights_size(e, &particles, &entries), VFE_OK);
  EXPECT_EQ(particles, int64_t(np));
  std::vector<int64_t> offsets(np + 1), cells(static_cast<std::size_t>(entries));
  std::vector<double> fractions(static_cast<std::size_t>(entries));
  ASSERT_EQ(vfe_weights(e, offsets.data(), cells.data(), fractions.data()), VFE_OK);
  const vfe::Engine::WeightsSize ws = serial.weights_size();
  std::vector<int64_t> so(static_cast<std::size_t>(ws.particles + 1)), sc(static_cast<std::size_t>(ws.entries));
  std::vector<double> sf(static_cast<std::size_t>(ws.entries));
  serial.weights(so, sc, sf);
  worst = 0;
  int64_t mismatched = 0;
  for (std::size_t i = 0; i < np; ++i) {
    const std::size_t k = static_cast<std::size_t>(std::find(scene.ids.begin(), scene.ids.end(), l.ids[i]) - scene.ids.begin());
    std::vector<std::pair<int64_t, double>> a, b;
    for (int64_t j = offsets[i]; j < offsets[i + 1]; ++j) a.emplace_back(cells[static_cast<std::size_t>(j)], fractions[static_cast<std::size_t>(j)]);
    for (int64_t j = so[k]; j < so[k + 1]; ++j) b.emplace_back(sc[static_cast<std::size_t>(j)], sf[static_cast<std::size_t>(j)]);
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    if (a.size() != b.size()) {
      ++mismatched;
      continue;
    }
    for (std::size_t j = 0; j < a.size(); ++j) {
      mismatched += a[j].first != b[j].first;
      worst = std::max(worst, std::abs(a[j].second - b[j].second));
    }
  }
  EXPECT_EQ(max_over_ranks(double(mismatched)), 0) << "particles whose cells differ from the serial engine's";
  EXPECT_LE(max_over_ranks(worst), 1e-12);
  vfe_destroy(e);
}

TEST(DistributedPolyMesh, RoutedParticlesEqualSerial) {
  const Mesh& mesh = kMeshes[1];
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  Scene scene = scenes(mesh, serial)[0];
  // Two spheres centred outside the mantle: they go to the owner of the nearest cell centre.
  scene.centres.insert(scene.centres.end(), {0.0205, 0.01, 0.01, 0.01, -0.0004, 0.03});
  scene.radii.insert(scene.radii.end(), {0.001, 0.0008});
  scene.ids.insert(scene.ids.end(), {-1, -2});
  // Each rank starts with every size-th particle, wherever it lies.
  Local given;
  for (std::size_t i = std::size_t(g_rank); i < scene.size(); i += std::size_t(g_size)) {
    given.centres.insert(given.centres.end(), &scene.centres[3 * i], &scene.centres[3 * i + 3]);
    given.radii.push_back(scene.radii[i]);
    given.ids.push_back(scene.ids[i]);
  }
  vfe_engine* e = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
  ASSERT_EQ(vfe_configure(e, "method=pmm"), VFE_OK);
  int64_t n = 0;
  double *centres = nullptr, *radii = nullptr;
  int64_t* ids = nullptr;
  ASSERT_EQ(vfe_mpi_route_particles(e, int64_t(given.radii.size()), given.centres.data(), given.radii.data(),
                                    given.ids.data(), &n, &centres, &radii, &ids),
            VFE_OK)
      << vfe_last_error(e);
  EXPECT_EQ(sum_over_ranks(double(n)), double(scene.size()));
  serial.configure("method=pmm");
  std::vector<double> expected(static_cast<std::size_t>(serial.cell_count()));
  serial.compute(view(scene.centres.data(), scene.radii.data(), scene.ids.data(), int64_t(scene.size())), expected);
  std::vector<double> field(cell_ids.size());
  const vfe_particles p = view(centres, radii, ids, n);
  EXPECT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_OK) << vfe_last_error(e);
  EXPECT_LE(max_difference(field, cell_ids, expected), 1e-12 * scene.largest_volume());
  std::free(centres);
  std::free(radii);
  std::free(ids);
  vfe_destroy(e);
}

TEST(DistributedPolyMesh, ParticleOnTheWrongRankIsRefusedEverywhere) {
  if (g_size == 1) GTEST_SKIP() << "needs two ranks";
  const Mesh& mesh = kMeshes[0];
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  const Scene scene = scenes(mesh, serial)[1];
  // Rank 0 also takes rank 1's first particle.
  std::vector<double> theirs;
  {
    const std::vector<int64_t> ids1 =
        vfe::read_polymesh_labels(kData + "decomposed/" + mesh.name + "_" + std::to_string(g_size) + "/processor1",
                                  "cellProcAddressing");
    const Local l1 = my_particles(scene, serial, ids1);
    ASSERT_FALSE(l1.radii.empty());
    theirs.assign(l1.centres.begin(), l1.centres.begin() + 3);
  }
  Local l = my_particles(scene, serial, cell_ids);
  if (g_rank == 0) {
    l.centres.insert(l.centres.end(), theirs.begin(), theirs.end());
    l.radii.push_back(0.001);
    l.ids.push_back(-7);
  }
  vfe_engine* e = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &e), VFE_OK) << vfe_last_error(nullptr);
  ASSERT_EQ(vfe_configure(e, "method=exact"), VFE_OK);
  std::vector<double> field(cell_ids.size(), 42.0);
  const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
  EXPECT_EQ(vfe_compute_particles(e, &p, field.data()), VFE_ERROR_INVALID_ARGUMENT);
  const std::string message = vfe_last_error(e);
  EXPECT_NE(message.find("(id -7)"), std::string::npos) << message;
  EXPECT_NE(message.find("owned by rank 1"), std::string::npos) << message;
  EXPECT_TRUE(std::all_of(field.begin(), field.end(), [](double v) { return v == 42.0; })) << "output was written";
  // The engine stays usable: without the stray particle the compute succeeds.
  if (g_rank == 0) {
    l.centres.erase(l.centres.end() - 3, l.centres.end());
    l.radii.pop_back();
    l.ids.pop_back();
  }
  const vfe_particles q = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
  EXPECT_EQ(vfe_compute_particles(e, &q, field.data()), VFE_OK) << vfe_last_error(e);
  vfe_destroy(e);
}

TEST(DistributedPolyMesh, ArraysFormEqualsFolderForm) {
  const Mesh& mesh = kMeshes[1];
  vfe::Engine serial(vfe::PolyMeshSpec{undecomposed(mesh)});
  const std::vector<int64_t> cell_ids = my_cell_ids(mesh);
  // What a host holding its decomposed mesh in memory passes.
  const vfe::PolyMeshBuffers b = vfe::read_polymesh_buffers(my_folder(mesh));
  std::vector<int64_t> point_ids, face_ids, coupled;
  if (g_size > 1) {
    point_ids = vfe::read_polymesh_labels(my_folder(mesh), "pointProcAddressing");
    face_ids = vfe::read_polymesh_labels(my_folder(mesh), "faceProcAddressing");
  } else {
    for (std::size_t i = 0; i < b.points.size() / 3; ++i) point_ids.push_back(int64_t(i));
    for (std::size_t i = 0; i < b.owner.size(); ++i) face_ids.push_back(int64_t(i) + 1);
  }
  for (const auto& patch : b.patches)
    if (patch.type == "processor")
      for (int64_t f = patch.start_face; f < patch.start_face + patch.n_faces; ++f) coupled.push_back(f);
  vfe_mpi_polymesh a{};
  a.n_points = int64_t(b.points.size() / 3);
  a.points = b.points.data();
  a.point_ids = point_ids.data();
  a.n_faces = int64_t(b.owner.size());
  a.face_offsets = b.face_offsets.data();
  a.face_points = b.face_points.data();
  a.owner = b.owner.data();
  a.n_internal_faces = int64_t(b.neighbour.size());
  a.neighbour = b.neighbour.data();
  a.face_ids = face_ids.data();
  a.cell_ids = cell_ids.data();
  a.n_coupled_faces = int64_t(coupled.size());
  a.coupled_faces = coupled.data();
  vfe_engine *from_arrays = nullptr, *from_folder = nullptr;
  ASSERT_EQ(vfe_mpi_create_polymesh_arrays(MPI_COMM_WORLD, &a, &from_arrays), VFE_OK) << vfe_last_error(nullptr);
  ASSERT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, my_folder(mesh).c_str(), &from_folder), VFE_OK);
  const Scene scene = scenes(mesh, serial)[0];
  const Local l = my_particles(scene, serial, cell_ids);
  const vfe_particles p = view(l.centres.data(), l.radii.data(), l.ids.data(), int64_t(l.radii.size()));
  std::vector<double> f1(cell_ids.size()), f2(cell_ids.size());
  for (vfe_engine* e : {from_arrays, from_folder}) ASSERT_EQ(vfe_configure(e, "method=pmm deterministic=1"), VFE_OK);
  ASSERT_EQ(vfe_compute_particles(from_arrays, &p, f1.data()), VFE_OK) << vfe_last_error(from_arrays);
  ASSERT_EQ(vfe_compute_particles(from_folder, &p, f2.data()), VFE_OK);
  EXPECT_EQ(max_over_ranks(f1 == f2 ? 0.0 : 1.0), 0.0) << "the arrays form differs from the folder form";
  // A coupled face that is internal is refused on every rank, with the reason.
  int64_t internal_face = 0;
  a.coupled_faces = &internal_face;
  a.n_coupled_faces = g_rank == 0 ? 1 : int64_t(coupled.size());
  if (g_rank != 0) a.coupled_faces = coupled.data();
  vfe_engine* bad = nullptr;
  EXPECT_EQ(vfe_mpi_create_polymesh_arrays(MPI_COMM_WORLD, &a, &bad), VFE_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(bad, nullptr);
  EXPECT_NE(std::string(vfe_last_error(nullptr)).find("is not a boundary face"), std::string::npos)
      << vfe_last_error(nullptr);
  vfe_destroy(from_arrays);
  vfe_destroy(from_folder);
}

TEST(DistributedPolyMesh, MissingFolderIsRefusedEverywhere) {
  vfe_engine* e = nullptr;
  const std::string dir = g_rank == g_size - 1 ? kData + "no_such_processor" : my_folder(kMeshes[0]);
  EXPECT_EQ(vfe_mpi_create_polymesh(MPI_COMM_WORLD, dir.c_str(), &e), VFE_ERROR_IO);
  EXPECT_EQ(e, nullptr);
  EXPECT_NE(std::string(vfe_last_error(nullptr)).find("no_such_processor"), std::string::npos)
      << vfe_last_error(nullptr);
}

}  // namespace

int main(int argc, char** argv) { return mpi_gtest_main(argc, argv, g_rank, g_size); }

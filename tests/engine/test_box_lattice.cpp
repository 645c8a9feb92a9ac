// PolyMeshes whose cells are a lattice of axis-aligned boxes: found once (and only then),
// computed on the grid of the same cells with the polyMesh's numbering and outside rules.
// The reference is the general polyMesh path (lattice=0), a different code path, and the
// grid of the same cells with its field permuted into the polyMesh's order.
#include <vfe/engine.hpp>

#include "block_mesh.hpp"
#include "box_lattice.hpp"
#include "particles.hpp"
#include "polymesh/polymesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>
#include <string>
#include <vector>

using vfe::test::Particles;
using vfe::test::run;

namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/openfoam/";

const char* const kMethods[] = {"method=direct",      "method=pmm",         "method=pmm particle_grid=125",
                                "method=exact",       "method=divided",     "method=gaussian",
                                "method=porous_cube", "method=big_particle"};
const char* const kOutside[] = {"outside=nearest", "outside=centre", "outside=drop"};

/// Spheres with centres over the bed's box [0, 0.02]^2 x [0, 0.06] grown by `beyond` on
/// every side: by default a millimetre beyond it, so that some reach outside and a few lie
/// wholly outside.
Particles spheres_over_box(std::uint32_t seed, int n, double beyond = 0.001) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(-beyond, 0.02 + beyond), z(-beyond, 0.06 + beyond), r(0.0003, 0.0009);
  Particles p;
  for (int i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng), zz = z(rng);
    p.add(x, y, zz, r(rng));
  }
  return p;
}

double largest_volume(const Particles& p) {
  const double r = *std::max_element(p.radii.begin(), p.radii.end());
  return 4.0 / 3.0 * std::numbers::pi * r * r * r;
}

/// The host's arrays of a polyMesh, optionally with its cells renumbered (cell c becomes
/// perm[c]; faces keep owner < neighbour by flipping those that would not).
struct MeshArrays {
  std::vector<double> points;
  std::vector<std::int64_t> offsets, face_points, owner, neighbour;

  MeshArrays(const vfe::PolyMesh& m, const std::vector<std::int64_t>& perm) {
    for (const auto& x : m.points()) points.insert(points.end(), {x[0], x[1], x[2]});
    offsets.push_back(0);
    for (std::int64_t f = 0; f < m.face_count(); ++f) {
      std::vector<std::int64_t> face(m.face(f).begin(), m.face(f).end());
      std::int64_t o = perm[static_cast<std::size_t>(m.owner(f))];
      if (f < m.internal_face_count()) {
        std::int64_t nb = perm[static_cast<std::size_t>(m.neighbour(f))];
        if (nb < o) {  // the face's normal must point from owner to neighbour
          std::swap(o, nb);
          std::reverse(face.begin(), face.end());
        }
        neighbour.push_back(nb);
      }
      owner.push_back(o);
      face_points.insert(face_points.end(), face.begin(), face.end());
      offsets.push_back(static_cast<std::int64_t>(face_points.size()));
    }
  }
  vfe::PolyMeshArrays view() const {
    vfe::PolyMeshArrays a;
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

std::vector<std::int64_t> identity(std::int64_t n) {
  std::vector<std::int64_t> perm(static_cast<std::size_t>(n));
  std::iota(perm.begin(), perm.end(), 0);
  return perm;
}

std::vector<std::int64_t> shuffled(std::int64_t n, std::uint32_t seed) {
  std::vector<std::int64_t> perm = identity(n);
  std::shuffle(perm.begin(), perm.end(), std::mt19937_64(seed));
  return perm;
}

/// The distinct coordinates of the mesh's points per axis (the lattice's nodes).
std::array<std::vector<double>, 3> point_nodes(const vfe::PolyMesh& m) {
  std::array<std::vector<double>, 3> nodes;
  for (int d = 0; d < 3; ++d) {
    for (const auto& x : m.points()) nodes[d].push_back(x[d]);
    std::sort(nodes[d].begin(), nodes[d].end());
    nodes[d].erase(std::unique(nodes[d].begin(), nodes[d].end()), nodes[d].end());
  }
  return nodes;
}

/// Lattice index of every polyMesh cell: its centre located on the grid of the nodes.
std::vector<std::int64_t> lattice_index_of_cells(const vfe::PolyMesh& m) {
  const auto nodes = point_nodes(m);
  std::vector<std::int64_t> index;
  for (std::int64_t c = 0; c < m.cell_count(); ++c) {
    const Eigen::Vector3d x = m.cell_centre(c);
    std::int64_t at[3];
    for (int d = 0; d < 3; ++d)
      at[d] = std::upper_bound(nodes[d].begin(), nodes[d].end(), x[d]) - nodes[d].begin() - 1;
    const auto nx = static_cast<std::int64_t>(nodes[0].size()) - 1, ny = static_cast<std::int64_t>(nodes[1].size()) - 1;
    index.push_back(at[0] + nx * (at[1] + ny * at[2]));
  }
  return index;
}

void expect_fields_near(const std::vector<double>& a, const std::vector<double>& b, double tol,
                        const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  double worst = 0;
  std::size_t at = 0;
  for (std::size_t c = 0; c < a.size(); ++c)
    if (std::abs(a[c] - b[c]) > worst) worst = std::abs(a[c] - b[c]), at = c;
  EXPECT_LE(worst, tol) << what << ": cell " << at << " " << a[at] << " vs " << b[at];
}

}  // namespace

TEST(BoxLattice, FoundOnTheBoxMeshesOnly) {
  const vfe::PolyMesh uniform = vfe::PolyMesh::read(kData + "box_uniform_10x10x30");
  const auto lu = vfe::detail::find_box_lattice(uniform);
  ASSERT_TRUE(lu);
  EXPECT_TRUE(lu->cartesian);  // evenly spaced nodes: the Cartesian grid
  EXPECT_EQ(lu->cells, (std::array<std::int64_t, 3>{10, 10, 30}));
  EXPECT_NEAR(lu->cartesian->spacing()[2], 0.002, 1e-15);
  const auto lg = vfe::detail::find_box_lattice(vfe::PolyMesh::read(kData + "box_graded"));
  ASSERT_TRUE(lg);
  EXPECT_TRUE(lg->rectilinear);
  EXPECT_EQ(lg->cells, (std::array<std::int64_t, 3>{16, 16, 40}));
  // Every slot holds one cell: the map is a permutation (plus the dropped slot).
  std::vector<std::int64_t> map = lg->cell_map;
  std::sort(map.begin(), map.end());
  EXPECT_EQ(map, identity(16 * 16 * 40 + 1));
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    EXPECT_FALSE(vfe::detail::find_box_lattice(vfe::PolyMesh::read(kData + mesh))) << mesh;
    vfe::Engine e(vfe::PolyMeshSpec{kData + mesh});
    EXPECT_EQ(e.last_report_value("lattice_cells"), 0.0) << mesh;
  }
  vfe::Engine e(vfe::PolyMeshSpec{kData + "box_uniform_10x10x30"});
  EXPECT_EQ(e.last_report_value("lattice_cells"), 3000.0);
}

TEST(BoxLattice, OneCellSlightlyNotABoxIsNoLattice) {
  const vfe::PolyMesh m = vfe::PolyMesh::read(kData + "box_uniform_10x10x30");
  // The domain's corner point belongs to one cell only: moved by 1e-6 of a cell, that cell's
  // three faces through it are no longer planes of a box.
  std::size_t corner = 0;
  for (std::size_t q = 0; q < m.points().size(); ++q)
    if (m.points()[q].isZero()) corner = q;
  MeshArrays a(m, identity(m.cell_count()));
  ASSERT_EQ(a.points[3 * corner], 0.0);
  {
    vfe::Engine e(a.view());
    EXPECT_EQ(e.last_report_value("lattice_cells"), 3000.0);
  }
  a.points[3 * corner] = 2e-9;
  vfe::Engine bent(a.view());
  EXPECT_EQ(bent.last_report_value("lattice_cells"), 0.0);
  const Particles p = spheres_over_box(3, 300);
  run(bent, p, "method=pmm");
  EXPECT_EQ(bent.last_report_value("lattice_particles"), 0.0);
  // The plane z = 0.03 moved by 1e-4 as a whole: the cells stay boxes on one (now graded)
  // lattice, and its field is the general path's.
  MeshArrays moved(m, identity(m.cell_count()));
  for (std::size_t q = 0; q < m.points().size(); ++q)
    if (std::abs(m.points()[q][2] - 0.03) < 1e-12) moved.points[3 * q + 2] += 1e-4;
  vfe::Engine e(moved.view());
  EXPECT_EQ(e.last_report_value("lattice_cells"), 3000.0);
  const std::vector<double> general = run(e, p, "method=pmm deterministic=1 lattice=0");
  const std::vector<double> lattice = run(e, p, "method=pmm deterministic=1 lattice=1");
  EXPECT_GT(e.last_report_value("lattice_particles"), 0.0);
  expect_fields_near(lattice, general, 1e-12 * largest_volume(p), "moved plane");
}

// Every method, every outside policy: the lattice path's field equals the general polyMesh
// path's (lattice=0) to 1e-12 of a particle's volume per cell, on the uniform and graded
// boxes and on the uniform box with its cells in a shuffled order; with sorted sums, and
// with private fields, where the uniform box takes the Cartesian grid's fused passes.
TEST(BoxLattice, EveryMethodEqualsTheGeneralPolyMeshPath) {
  const Particles p = spheres_over_box(11, 1500);
  const double tol = 1e-12 * largest_volume(p);
  const vfe::PolyMesh uniform = vfe::PolyMesh::read(kData + "box_uniform_10x10x30");
  const vfe::PolyMesh graded = vfe::PolyMesh::read(kData + "box_graded");
  const MeshArrays arrays[] = {MeshArrays(uniform, identity(uniform.cell_count())),
                               MeshArrays(graded, identity(graded.cell_count())),
                               MeshArrays(uniform, shuffled(uniform.cell_count(), 5))};
  const char* names[] = {"box_uniform", "box_graded", "box_uniform shuffled"};
  for (int m = 0; m < 3; ++m) {
    vfe::Engine e(arrays[m].view());
    ASSERT_GT(e.last_report_value("lattice_cells"), 0) << names[m];
    for (const char* method : kMethods)
      for (const char* outside : kOutside)
        for (const char* sums : {"deterministic=1 accumulation=auto", "deterministic=0 accumulation=private"}) {
          const std::string opts = std::string(method) + " " + outside + " " + sums;
          const std::string what = std::string(names[m]) + ": " + opts;
          const std::vector<double> general = run(e, p, opts + " lattice=0");
          EXPECT_EQ(e.last_report_value("lattice_particles"), 0.0) << what;
          const double outside_general = e.last_report_value("outside_particles");
          const double dropped_general = e.last_report_value("dropped_volume");
          const std::vector<double> lattice = run(e, p, opts + " lattice=1");
          EXPECT_GT(e.last_report_value("lattice_particles"), 0.5 * double(p.radii.size())) << what;
          if (m != 1 && std::string(method) == "method=direct")  // the Cartesian grid's pass, renumbered
            EXPECT_EQ(e.last_report_value("fused_pass"), std::string(sums).ends_with("private") ? 1.0 : 0.0) << what;
          EXPECT_EQ(e.last_report_value("outside_particles"), outside_general) << what;
          EXPECT_NEAR(e.last_report_value("dropped_volume"), dropped_general, tol) << what;
          // Volume is conserved: what the cells hold plus what was dropped.
          EXPECT_NEAR(vfe::test::total(lattice) + e.last_report_value("dropped_volume"), p.volume(),
                      1e-12 * p.volume())
              << what;
          expect_fields_near(lattice, general, tol, what);
        }
  }
}

// The lattice path equals the grid of the same cells, its field permuted into the
// polyMesh's order. outside=drop: the grids give volume beyond a side to the cells along
// it, the polyMesh to the cell nearest to the centre. On the graded box the spheres keep
// 3 mm inside (more than any method's footprint): near its sides the polyMesh's rules
// differ from the rectilinear grid's (pmm's template is sized by the cell whose centre is
// nearest, big_particle counts real cells' centres only).
TEST(BoxLattice, EqualsTheGridOfTheSameCellsPermuted) {
  const Particles p = spheres_over_box(12, 1500), inner = spheres_over_box(12, 1500, -0.003);
  const double tol = 1e-12 * largest_volume(p);
  const vfe::PolyMesh uniform = vfe::PolyMesh::read(kData + "box_uniform_10x10x30");
  const vfe::PolyMesh graded = vfe::PolyMesh::read(kData + "box_graded");
  const std::vector<std::int64_t> perm = shuffled(uniform.cell_count(), 9);
  const MeshArrays shuffled_uniform(uniform, perm);
  vfe::Engine cartesian(vfe::test::grid(0.002, 10, 10, 30));
  vfe::Engine rectilinear(vfe::RectilinearGridSpec{point_nodes(graded)});
  vfe::Engine poly_uniform(shuffled_uniform.view());
  vfe::Engine poly_graded(vfe::PolyMeshSpec{kData + "box_graded"});
  const std::vector<std::int64_t> graded_index = lattice_index_of_cells(graded);
  for (const char* method : kMethods) {
    const std::string opts = std::string(method) + " outside=drop deterministic=1";
    const std::vector<double> grid_u = run(cartesian, p, opts), grid_g = run(rectilinear, inner, opts);
    const std::vector<double> poly_u = run(poly_uniform, p, opts), poly_g = run(poly_graded, inner, opts);
    EXPECT_EQ(poly_graded.last_report_value("lattice_particles"), double(inner.radii.size()));
    std::vector<double> permuted_u(grid_u.size()), permuted_g(grid_g.size());
    for (std::size_t c = 0; c < grid_u.size(); ++c) permuted_u[static_cast<std::size_t>(perm[c])] = grid_u[c];
    for (std::size_t c = 0; c < grid_g.size(); ++c)
      permuted_g[c] = grid_g[static_cast<std::size_t>(graded_index[c])];
    expect_fields_near(poly_u, permuted_u, tol, std::string("uniform ") + method);
    expect_fields_near(poly_g, permuted_g, tol, std::string("graded ") + method);
  }
}

// direct with two threads on a lattice of 85^3 cells (above the engine's 600000) sorts its
// deposits into bins, by the polyMesh's cells (here numbered in shuffled order): the grid of
// the same cells with its field permuted, and the general polyMesh path where spheres reach
// outside (nearest).
TEST(BoxLattice, BinnedDirectTakesThePolyMeshNumbering) {
  const int n = 85;
  const double side = 0.25 * n;
  const vfe::PolyMesh block(vfe::test::block_mesh({vfe::test::nodes(n, 0, side), vfe::test::nodes(n, 0, side),
                                                   vfe::test::nodes(n, 0, side)}));
  const std::vector<std::int64_t> perm = shuffled(block.cell_count(), 10);
  const MeshArrays arrays(block, perm);
  vfe::Engine poly(arrays.view()), cartesian(vfe::test::grid(0.25, n, n, n));
  // Enough spheres that accumulation=auto takes per-thread sums, not atomics.
  const Particles p = vfe::test::random_spheres(53, 70000, -0.5, side + 0.5, 0.02, 0.2);
  const double tol = 1e-15 * p.volume();
  const std::vector<double> a = run(poly, p, "method=direct threads=2 outside=drop");
  EXPECT_GT(poly.last_report_value("binned_regions"), 0.0);
  EXPECT_GT(poly.last_report_value("lattice_particles"), 0.0);
  const std::vector<double> b = run(cartesian, p, "method=direct threads=2 outside=drop accumulation=atomic");
  std::vector<double> permuted(b.size());
  for (std::size_t c = 0; c < b.size(); ++c) permuted[static_cast<std::size_t>(perm[c])] = b[c];
  expect_fields_near(a, permuted, tol, "outside=drop");
  const std::vector<double> near = run(poly, p, "method=direct threads=2 outside=nearest");
  EXPECT_GT(poly.last_report_value("binned_regions"), 0.0);
  const std::vector<double> general = run(poly, p, "method=direct threads=2 outside=nearest lattice=0");
  expect_fields_near(near, general, tol, "outside=nearest");
}

// The weights, deposit and interpolate stay in the polyMesh's numbering.
TEST(BoxLattice, WeightsInThePolyMeshNumbering) {
  const Particles p = spheres_over_box(13, 600);
  const vfe::PolyMesh uniform = vfe::PolyMesh::read(kData + "box_uniform_10x10x30");
  const MeshArrays a(uniform, shuffled(uniform.cell_count(), 21));
  vfe::Engine e(a.view());
  std::vector<double> values(p.radii.size());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 1.0 + double(i % 7);
  std::vector<double> cell_field(static_cast<std::size_t>(e.cell_count()));
  for (std::size_t c = 0; c < cell_field.size(); ++c) cell_field[c] = std::sin(double(c));
  std::vector<double> deposited[2], interpolated[2];
  for (int lattice = 0; lattice < 2; ++lattice) {
    run(e, p, "method=exact deterministic=1 weights=1 lattice=" + std::to_string(lattice));
    deposited[lattice].resize(cell_field.size());
    interpolated[lattice].resize(values.size());
    e.deposit(1, values, deposited[lattice]);
    e.interpolate(1, cell_field, interpolated[lattice]);
  }
  expect_fields_near(deposited[1], deposited[0], 1e-12 * 7, "deposit");
  expect_fields_near(interpolated[1], interpolated[0], 1e-12, "interpolate");
}

// The engine's info log names the lattice and how many particles took the grid's path.
TEST(BoxLattice, LogNamesTheLattice) {
  vfe::Engine e(vfe::PolyMeshSpec{kData + "box_graded"});
  std::vector<std::string> messages;
  e.set_log_callback(
      [](int, const char* message, void* user) { static_cast<std::vector<std::string>*>(user)->push_back(message); },
      &messages);
  const Particles p = spheres_over_box(14, 200, -0.003);
  run(e, p, "method=exact log_level=info");
  const auto has = [&](const std::string& text) {
    return std::any_of(messages.begin(), messages.end(),
                       [&](const std::string& m) { return m.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(has("a lattice of 16 x 16 x 40 box cells, graded: 200 particles on the rectilinear grid's path"));
  messages.clear();
  run(e, p, "method=exact lattice=0");
  EXPECT_TRUE(has("not used: lattice=0"));
}

// method=exact on OpenFOAM polyMeshes: the Cartesian exact field on the uniform box, the
// box closed form on the graded box, volume conservation per particle and over the packed
// bed on meshes with warped faces, pmm converging to it, and the spatial hash's box query
// against brute force.
#include <vfe/engine.hpp>

#include "methods/polymesh.hpp"
#include "particles.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"

#include <vfe/kernels/sphere_box_overlap.hpp>
#include <vfe/kernels/sphere_polyhedron_overlap.hpp>

#include <gtest/gtest.h>

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using vfe::test::Particles;
using vfe::test::packed_bed;
using vfe::test::l1;
using vfe::test::total;

namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

/// Brute force: each cell's sum over the particles of the general sphere-polyhedron overlap
/// of its whole boundary.
std::vector<double> general_overlaps(const vfe::PolyMesh& mesh, const Particles& p) {
  std::vector<double> field(static_cast<std::size_t>(mesh.cell_count()), 0.0);
  vfe::detail::Scratch s;
  for (std::size_t i = 0; i < p.radii.size(); ++i) {
    const Eigen::Vector3d centre(p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2]);
    const double r = p.radii[i];
    for (std::int64_t c = 0; c < mesh.cell_count(); ++c) {
      if (mesh.cell_bounds(c).squaredExteriorDistance(centre) >= r * r) continue;
      vfe::detail::cell_boundary(mesh, c, s);
      field[static_cast<std::size_t>(c)] +=
          vfe::kernels::sphere_polyhedron_overlap(centre, r, s.cell_points, s.cell_face_offsets, s.cell_face_points);
    }
  }
  return field;
}

}  // namespace

TEST(PolyMeshExact, UniformBoxMatchesTheCartesianExact) {
  vfe::Engine poly(vfe::PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
  vfe::CartesianGridSpec spec;
  spec.spacing = {0.002, 0.002, 0.002};
  spec.cells = {10, 10, 30};
  vfe::Engine cart(spec);
  ASSERT_EQ(poly.cell_count(), cart.cell_count());

  // The bed, and spheres of up to three cells placed anywhere in and around the box
  // (centres on faces, edges and corners of cells included).
  Particles bed = packed_bed();
  Particles loose;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-0.1, 1.1), radius(0.0002, 0.006);
  std::uniform_int_distribution<int> node(-1, 31);
  for (int i = 0; i < 300; ++i) {
    double x = 0.02 * u(rng), y = 0.02 * u(rng), z = 0.06 * u(rng);
    if (i % 3 == 0) x = 0.002 * std::clamp(node(rng), 0, 10);
    if (i % 6 == 0) y = 0.002 * std::clamp(node(rng), 0, 10);
    if (i % 12 == 0) z = 0.002 * node(rng);
    loose.add(x, y, z, radius(rng));
  }
  std::vector<double> fp(poly.cell_count()), fc(cart.cell_count());
  for (const Particles* p : {&bed, &loose}) {
    // outside=nearest only for the bed: a loose centre on a cell face, beyond the mesh, is
    // as near to two cell centres, and the two engines break that tie differently.
    for (const char* outside : {"drop", "nearest"}) {
      if (p == &loose && std::string(outside) == "nearest") continue;
      const std::string options = std::string("method=exact deterministic=1 outside=") + outside;
      poly.configure(options + " lattice=0");  // the general polyMesh path
      cart.configure(options);
      poly.compute(p->view(), fp);
      cart.compute(p->view(), fc);
      EXPECT_LT(l1(fp, fc), 1e-12 * p->volume()) << options;
      EXPECT_NEAR(poly.last_report().dropped_volume, cart.last_report().dropped_volume, 1e-12 * p->volume());
      EXPECT_NEAR(total(fp) + poly.last_report().dropped_volume, p->volume(), 1e-12 * p->volume()) << options;
    }
    EXPECT_GT(poly.last_report().fast_path_particles, 0);
    EXPECT_GT(poly.last_report().sub_elements, 0);
  }
}

TEST(PolyMeshExact, GradedBoxCellsMatchTheBoxClosedForm) {
  // box_graded's cells are axis-aligned boxes of graded sizes: each cell's field is the sum
  // of sphere_box_overlap over the particles.
  const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/box_graded");
  vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/box_graded"});
  const Particles bed = packed_bed(2000);
  std::vector<double> f(e.cell_count()), expected(e.cell_count(), 0.0), lattice(e.cell_count());
  e.configure("method=exact outside=drop lattice=1");  // on the rectilinear grid of the same cells
  e.compute(bed.view(), lattice);
  e.configure("method=exact outside=drop lattice=0");  // the general polyMesh path
  e.compute(bed.view(), f);
  for (std::int64_t c = 0; c < mesh.cell_count(); ++c) {
    const Eigen::AlignedBox3d& box = mesh.cell_bounds(c);
    ASSERT_NEAR(box.volume(), mesh.cell_volume(c), 1e-12 * box.volume()) << "cell " << c << " is not a box";
  }
  for (std::size_t i = 0; i < bed.radii.size(); ++i) {
    const Eigen::Vector3d centre(bed.centres[3 * i], bed.centres[3 * i + 1], bed.centres[3 * i + 2]);
    const double r = bed.radii[i];
    for (std::int64_t c = 0; c < mesh.cell_count(); ++c) {
      const Eigen::AlignedBox3d& box = mesh.cell_bounds(c);
      if (box.squaredExteriorDistance(centre) < r * r)
        expected[static_cast<std::size_t>(c)] += vfe::kernels::sphere_box_overlap(centre, r, box.min(), box.max());
    }
  }
  EXPECT_LT(l1(f, expected), 1e-12 * bed.volume());
  EXPECT_LT(l1(lattice, expected), 1e-12 * bed.volume());
}

TEST(PolyMeshExact, VolumeIsConservedOnCurvedAndSnappyMeshes) {
  // Both meshes have warped faces (fans at the face apex) and do not cover the whole bed.
  const Particles bed = packed_bed();
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/" + mesh});
    std::vector<double> f(e.cell_count());
    e.configure("method=exact outside=drop");
    e.compute(bed.view(), f);
    EXPECT_NEAR(total(f) + e.last_report().dropped_volume, bed.volume(), 1e-12 * bed.volume()) << mesh;
    EXPECT_GE(*std::min_element(f.begin(), f.end()), 0.0) << mesh;
    EXPECT_GT(e.last_report().dropped_volume, 1e-3 * bed.volume()) << mesh;
    e.configure("method=exact outside=nearest");
    e.compute(bed.view(), f);
    EXPECT_NEAR(total(f), bed.volume(), 1e-12 * bed.volume()) << mesh;
    // Cut cells that are not boxes take the located sum; the general formula only near a
    // face plane or edge line (docs/polymesh.md, "A located centre").
    const double located = e.last_report_value("exact_located_cells");
    const double general = e.last_report_value("exact_general_cells");
    EXPECT_GT(located, 0) << mesh;
    EXPECT_LT(general, 0.01 * located) << mesh;
    RecordProperty(std::string(mesh) + "_general_cells", std::to_string(general) + " of " +
                                                             std::to_string(general + located));
  }
}

// The cylinder's core cells are boxes and take the sphere-box closed form: every cell's field
// equals the sum of the general sphere-polyhedron overlaps of its faces.
TEST(PolyMeshExact, BoxCellsOfACurvedMeshMatchThePolyhedronOverlap) {
  const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/cylinder_ogrid_coarse");
  std::int64_t boxes = 0;
  for (std::int64_t c = 0; c < mesh.cell_count(); ++c) {
    Eigen::AlignedBox3d box;
    boxes += vfe::detail::cell_is_box(mesh, c, box);
  }
  ASSERT_GT(boxes, 0);
  ASSERT_LT(boxes, mesh.cell_count());
  vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"});
  ASSERT_EQ(e.last_report_value("lattice_cells"), 0.0);
  const Eigen::AlignedBox3d bounds = mesh.bounds();
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> t(0.0, 1.0), radius(0.0003, 0.0015);
  Particles p;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d x = bounds.min() + bounds.sizes().cwiseProduct(Eigen::Vector3d(t(rng), t(rng), t(rng)));
    p.add(x[0], x[1], x[2], radius(rng));
  }
  std::vector<double> f(e.cell_count());
  e.configure("method=exact outside=drop");
  e.compute(p.view(), f);
  const std::vector<double> expected = general_overlaps(mesh, p);
  const double v_max = 4.0 / 3.0 * 3.14159265358979 * std::pow(0.0015, 3);
  double worst = 0;
  for (std::size_t c = 0; c < f.size(); ++c) worst = std::max(worst, std::abs(f[c] - expected[c]));
  EXPECT_LT(worst, 1e-12 * v_max);
  EXPECT_GT(total(f), 0.1 * p.volume());
}

// exact takes the centre's side of each cut cell from point location and gives the kernel
// only the faces that may reach into the ball; centres on and near faces, edges and fan
// apexes (where that side is decided by the tie rule, or the kernel declines and the whole
// surface is used) must still give every cell the general overlap of its whole boundary.
TEST(PolyMeshExact, CentresOnAndNearFacesMatchTheGeneralOverlap) {
  const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/cylinder_ogrid_coarse");
  vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/cylinder_ogrid_coarse"});
  e.configure("method=exact outside=drop threads=1");
  std::mt19937_64 rng(10);
  std::uniform_int_distribution<std::int64_t> pick(0, mesh.face_count() - 1);
  std::uniform_real_distribution<double> radius(0.0003, 0.0012), unit(0, 1);
  Particles p;
  int warped = 0;
  for (int i = 0; i < 150; ++i) {
    const std::int64_t f = pick(rng);
    warped += mesh.face_plane_triangle(f) < 0;
    const Eigen::Vector3d apex = mesh.face_apex(f), n = mesh.face_normal(f);
    const Eigen::Vector3d corner = mesh.points()[static_cast<std::size_t>(mesh.face(f)[0])];
    const Eigen::Vector3d inner = apex + unit(rng) * (corner - apex) / 2;  // on a spoke of the fan
    for (const Eigen::Vector3d& x : {apex, corner, inner, Eigen::Vector3d(apex + 1e-16 * n),
                                     Eigen::Vector3d(apex - 3e-15 * n), Eigen::Vector3d(inner + 1e-12 * n),
                                     Eigen::Vector3d(inner - 1e-9 * n), Eigen::Vector3d(inner + 2e-5 * n)})
      p.add(x[0], x[1], x[2], radius(rng));
  }
  ASSERT_GT(warped, 10);
  std::vector<double> f(e.cell_count(), 0.0), g(e.cell_count());
  double located = 0, general = 0;
  for (std::size_t i = 0; i < p.radii.size(); ++i) {  // one at a time: each particle's volume must add up
    Particles one;
    one.add(p.centres[3 * i], p.centres[3 * i + 1], p.centres[3 * i + 2], p.radii[i]);
    e.compute(one.view(), g);
    EXPECT_NEAR(total(g) + e.last_report().dropped_volume, one.volume(), 1e-12 * one.volume()) << "particle " << i;
    for (std::size_t c = 0; c < g.size(); ++c) f[c] += g[c];
    located += e.last_report_value("exact_located_cells");
    general += e.last_report_value("exact_general_cells");
  }
  // Both formulas served: the centres near apexes and spokes take the general one.
  EXPECT_GT(located, 0);
  EXPECT_GT(general, 0);
  const std::vector<double> expected = general_overlaps(mesh, p);
  const double v_max = 4.0 / 3.0 * 3.14159265358979 * std::pow(0.0012, 3);
  double worst = 0;
  for (std::size_t c = 0; c < f.size(); ++c) worst = std::max(worst, std::abs(f[c] - expected[c]));
  EXPECT_LT(worst, 1e-12 * v_max);
}

TEST(PolyMeshExact, EachParticleInsideTheMeshIsConserved) {
  // One sphere at a time, spanning several cells but inside the mesh: the cells' overlaps
  // add up to the sphere (nothing may be dropped) whatever the faces.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/" + mesh});
    e.configure("method=exact outside=drop threads=1");
    std::vector<double> f(e.cell_count());
    int tested = 0;
    while (tested < 100) {
      Particles one;
      one.add(0.002 + 0.016 * u(rng), 0.002 + 0.016 * u(rng), 0.002 + 0.056 * u(rng), 0.0003 + 0.0015 * u(rng));
      e.compute(one.view(), f);
      if (e.last_report().outside_particles != 0) continue;  // reaches beyond the mesh
      ++tested;
      EXPECT_NEAR(total(f), one.volume(), 1e-13 * one.volume()) << mesh;
      EXPECT_EQ(e.last_report().dropped_volume, 0.0);
    }
  }
}

TEST(PolyMeshExact, PmmConvergesToExact) {
  const Particles bed = packed_bed(1500);
  for (const char* mesh : {"box_graded", "cylinder_ogrid_coarse"}) {
    vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/" + mesh});
    std::vector<double> exact(e.cell_count()), f(e.cell_count());
    e.configure("method=exact outside=drop");
    e.compute(bed.view(), exact);
    double previous = 0;
    for (const int n : {27, 125, 1000, 8000}) {
      e.configure("method=pmm outside=drop particle_grid=" + std::to_string(n));
      e.compute(bed.view(), f);
      const double error = l1(f, exact) / bed.volume();
      if (n == 27) {
        EXPECT_LT(error, 0.1) << mesh;
      } else {
        EXPECT_LT(error, 0.7 * previous) << mesh << " n " << n;
      }
      previous = error;
    }
    EXPECT_LT(previous, 2e-3) << mesh;
  }
}

TEST(PolyMeshExact, HashBoxQueryFindsEveryOverlappingCellOnce) {
  const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/cylinder_ogrid_coarse");
  const vfe::SpatialHash hash(mesh);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 1.2), size(0, 0.008);
  std::vector<std::int64_t> found, expected;
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d lo(0.02 * u(rng), 0.02 * u(rng), 0.06 * u(rng));
    const Eigen::AlignedBox3d box(lo, lo + Eigen::Vector3d(size(rng), size(rng), size(rng)));
    hash.cells_in_box(box, found);
    expected.clear();
    for (std::int64_t c = 0; c < mesh.cell_count(); ++c)
      if (mesh.cell_bounds(c).intersects(box)) expected.push_back(c);
    std::sort(found.begin(), found.end());
    ASSERT_EQ(found, expected) << trial;
  }
}

// exact finds a ball's cells by walking from the centre's cell across the faces the ball
// reaches; a baffle (two boundary faces in one plane, here between the two cells of a
// 2 x 1 x 1 block) stops that walk, so the cells beyond it come from the spatial hash.
TEST(PolyMeshExact, ABallAcrossABaffleFindsTheCellsBeyondIt) {
  // Points x fastest: (i, j, k) at index i + 3 (j + 2 k), i in 0..2.
  std::vector<double> points;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 3; ++i) points.insert(points.end(), {double(i), double(j), double(k)});
  const auto pid = [](int i, int j, int k) { return std::int64_t(i + 3 * (j + 2 * k)); };
  std::vector<std::int64_t> offsets{0}, face_points, owner;
  const auto face = [&](std::initializer_list<std::int64_t> f, std::int64_t cell) {
    face_points.insert(face_points.end(), f);
    offsets.push_back(std::int64_t(face_points.size()));
    owner.push_back(cell);
  };
  for (int c = 0; c < 2; ++c) {  // every face of both cells on the boundary, outward
    const int i0 = c, i1 = c + 1;
    face({pid(i0, 0, 0), pid(i0, 0, 1), pid(i0, 1, 1), pid(i0, 1, 0)}, c);  // -x (cell 1's: the baffle)
    face({pid(i1, 0, 0), pid(i1, 1, 0), pid(i1, 1, 1), pid(i1, 0, 1)}, c);  // +x (cell 0's: the baffle)
    face({pid(i0, 0, 0), pid(i1, 0, 0), pid(i1, 0, 1), pid(i0, 0, 1)}, c);  // -y
    face({pid(i0, 1, 0), pid(i0, 1, 1), pid(i1, 1, 1), pid(i1, 1, 0)}, c);  // +y
    face({pid(i0, 0, 0), pid(i0, 1, 0), pid(i1, 1, 0), pid(i1, 0, 0)}, c);  // -z
    face({pid(i0, 0, 1), pid(i1, 0, 1), pid(i1, 1, 1), pid(i0, 1, 1)}, c);  // +z
  }
  vfe::PolyMeshArrays arrays;
  arrays.n_points = std::int64_t(points.size() / 3);
  arrays.points = points.data();
  arrays.n_faces = std::int64_t(owner.size());
  arrays.face_offsets = offsets.data();
  arrays.face_points = face_points.data();
  arrays.owner = owner.data();
  vfe::Engine e(arrays);
  e.configure("method=exact lattice=0 outside=drop threads=1");
  for (const double x : {0.9, 1.1}) {  // the centre on either side of the baffle
    Particles one;
    one.add(x, 0.5, 0.45, 0.3);
    std::vector<double> f(2);
    e.compute(one.view(), f);
    const Eigen::Vector3d c(x, 0.5, 0.45);
    EXPECT_NEAR(f[0], vfe::kernels::sphere_box_overlap(c, 0.3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1)),
                1e-14 * one.volume());
    EXPECT_NEAR(f[1], vfe::kernels::sphere_box_overlap(c, 0.3, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 1, 1)),
                1e-14 * one.volume());
    EXPECT_GT(std::min(f[0], f[1]), 0.1 * one.volume());
    EXPECT_EQ(e.last_report().dropped_volume, 0.0);
  }
}

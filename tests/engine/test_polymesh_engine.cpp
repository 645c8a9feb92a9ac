// The engine on OpenFOAM polyMeshes: same fields as the Cartesian grid of the same
// cells, conservation on the cylinder and snappyHexMesh meshes with real particles, pmm's
// sub-elements where the point locator puts them.
#include <vfe/engine.hpp>

#include "methods/polymesh.hpp"

#include <vfe/kernels/divided.hpp>
#include "options.hpp"
#include "particles.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"

#include <vfe/kernels/particle_template.hpp>

#include <gtest/gtest.h>

#include <numbers>
#include <numeric>

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using vfe::test::Particles;
using vfe::test::packed_bed;
using vfe::test::total;

namespace {

const std::string kData = std::string(VFE_SOURCE_DIR) + "/data/";

}  // namespace

TEST(PolyMeshEngine, UniformBoxMatchesTheCartesianGrid) {
  vfe::Engine poly(vfe::PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
  vfe::CartesianGridSpec spec;
  spec.spacing = {0.002, 0.002, 0.002};
  spec.cells = {10, 10, 30};
  vfe::Engine cart(spec);
  ASSERT_TRUE(poly.is_polymesh());
  ASSERT_EQ(poly.cell_count(), cart.cell_count());
  std::vector<double> vp(poly.cell_count()), vc(cart.cell_count());
  poly.cell_volumes(vp);
  cart.cell_volumes(vc);
  for (std::size_t c = 0; c < vp.size(); ++c) ASSERT_NEAR(vp[c], vc[c], 1e-12 * vc[c]) << c;

  const Particles p = packed_bed();
  ASSERT_EQ(p.radii.size(), 20000u);
  std::vector<double> fp(poly.cell_count()), fc(cart.cell_count());
  for (const char* m : {"method=direct", "method=pmm particle_grid=64", "method=pmm"}) {
    poly.configure(std::string(m) + " deterministic=1 lattice=0");  // the general polyMesh path
    cart.configure(std::string(m) + " deterministic=1");
    poly.compute(p.view(), fp);
    cart.compute(p.view(), fc);
    double diff = 0;
    for (std::size_t c = 0; c < fp.size(); ++c) diff += std::abs(fp[c] - fc[c]);
    // Same cells, same order; sub-elements within rounding of a face may fall either side.
    EXPECT_LT(diff, 1e-9 * p.volume()) << m;
    EXPECT_NEAR(total(fp), p.volume(), 1e-12 * p.volume()) << m;
  }
}

TEST(PolyMeshEngine, VolumeIsConservedOnCurvedAndSnappyMeshes) {
  const Particles p = packed_bed();
  for (const char* mesh : {"cylinder_ogrid_coarse", "snappy_obstacle", "box_graded"}) {
    vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/" + mesh});
    std::vector<double> f(e.cell_count());
    for (const char* m : {"method=direct", "method=pmm particle_grid=27"}) {
      e.configure(std::string(m) + " outside=nearest");
      e.compute(p.view(), f);
      EXPECT_NEAR(total(f), p.volume(), 1e-12 * p.volume()) << mesh << " " << m;
      e.configure(std::string(m) + " outside=drop");
      e.compute(p.view(), f);
      EXPECT_NEAR(total(f) + e.last_report().dropped_volume, p.volume(), 1e-12 * p.volume()) << mesh << " " << m;
      if (std::string(mesh) != "box_graded") {
        EXPECT_GT(e.last_report().dropped_volume, 0.0) << mesh;
      }
    }
  }
}

TEST(PolyMeshEngine, UnsupportedMethodsAndBadPaths) {
  vfe::Engine e(vfe::PolyMeshSpec{kData + "openfoam/box_uniform_10x10x30"});
  Particles p;
  p.centres = {0.005, 0.005, 0.005};
  p.radii = {0.0005};
  std::vector<double> f(e.cell_count(), 3.0);
  // A method a mesh kind cannot run is refused by configure at once, naming alternatives,
  // and the engine keeps its options.
  try {
    e.configure("method=trilinear");
    FAIL();
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
    EXPECT_NE(std::string(err.what()).find("polyMesh"), std::string::npos) << err.what();
    EXPECT_NE(std::string(err.what()).find("pmm"), std::string::npos) << err.what();
  }
  EXPECT_EQ(e.option("method"), "pmm");
  e.compute(p.view(), f);
  EXPECT_NEAR(std::accumulate(f.begin(), f.end(), 0.0), 4.0 / 3.0 * std::numbers::pi * 1.25e-10, 1e-22);
  try {
    vfe::Engine bad(vfe::PolyMeshSpec{kData + "openfoam/no_such_case"});
    FAIL();
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_IO);
  }
}

namespace {

struct SubElementCheck {
  std::int64_t particles = 0, points = 0, outside = 0, brute_force = 0;
};

/// Runs pmm's polyMesh driver with template t on every stride-th particle of bed and
/// compares each particle's deposits with the plain per-point location: every sub-element
/// by CellLocator::locate_from from the centre's cell (every 61st also by brute force),
/// outside ones by the policy (nearest: KdTreeLocator::nearest_cell of the point).
void check_sub_elements(const vfe::PolyMesh& mesh, const vfe::CellLocator& locator, const Particles& bed,
                        const vfe::kernels::ParticleTemplate& t, std::size_t stride, vfe::Outside outside,
                        vfe::detail::Scratch& s, SubElementCheck& count,
                        vfe::Orientation orientation = vfe::Orientation::random) {
  vfe::Options opts;
  opts.outside = outside;
  opts.orientation = orientation;
  const vfe::kernels::ParticleTemplate divided = vfe::kernels::make_divided_template();
  const vfe::detail::PolyContext ctx{{opts, {}, divided}, &locator};
  std::map<std::int64_t, double> expected;
  for (std::size_t i = 0; i < bed.radii.size(); i += stride) {
    const double r = bed.radii[i];
    const Eigen::Vector3d centre(bed.centres[3 * i], bed.centres[3 * i + 1], bed.centres[3 * i + 2]);
    const vfe::detail::Particle p{static_cast<std::int64_t>(i), centre, r, 4.0 / 3.0 * std::numbers::pi * r * r * r,
                                  nullptr, static_cast<std::uint64_t>(i)};
    s.deposits.clear();
    vfe::detail::polymesh_points(ctx, s, p, t, vfe::detail::particle_rotation(opts, p), opts.outside,
                                 locator.locate(p.centre));

    expected.clear();
    const std::int64_t centre_cell = locator.locate(p.centre);
    const Eigen::Matrix3d transform = vfe::detail::particle_rotation(opts, p) * p.radius;
    for (std::size_t q = 0; q < t.size(); ++q) {
      const Eigen::Vector3d x = p.centre + transform * t.points[q];
      std::int64_t cell = locator.locate_from(x, centre_cell);
      if (count.points++ % 61 == 0) {
        ASSERT_EQ(cell, vfe::locate_brute_force(mesh, x)) << "particle " << i << " point " << q;
        ++count.brute_force;
      }
      if (cell < 0) {
        ++count.outside;
        switch (outside) {
          case vfe::Outside::nearest: cell = locator.nearest_cell(x); break;
          case vfe::Outside::centre: cell = centre_cell >= 0 ? centre_cell : locator.nearest_cell(p.centre); break;
          default: cell = mesh.cell_count(); break;  // the dropped-volume slot
        }
      }
      expected[cell] += p.volume * t.fractions[q];
    }
    std::sort(s.deposits.begin(), s.deposits.end(),
              [](const vfe::detail::Deposit& a, const vfe::detail::Deposit& b) { return a.cell < b.cell; });
    ASSERT_EQ(s.deposits.size(), expected.size()) << "particle " << i;
    std::size_t k = 0;
    for (const auto& [cell, volume] : expected) {
      ASSERT_EQ(s.deposits[k].cell, cell) << "particle " << i;
      EXPECT_NEAR(s.deposits[k].volume, volume, 1e-13 * p.volume) << "particle " << i << " cell " << cell;
      ++k;
    }
    ++count.particles;
  }
}

/// A random cell, one of its faces, and that face's unit normal pointing out of the cell.
struct CellFace {
  std::int64_t cell, face;
  Eigen::Vector3d normal;
};
CellFace random_cell_face(const vfe::PolyMesh& mesh, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const auto c = static_cast<std::int64_t>(u(rng) * double(mesh.cell_count())) % mesh.cell_count();
  const auto faces = mesh.cell_faces(c);
  const std::int64_t f = faces[static_cast<std::size_t>(u(rng) * double(faces.size())) % faces.size()];
  return {c, f, mesh.owner(f) == c ? Eigen::Vector3d(mesh.face_normal(f)) : Eigen::Vector3d(-mesh.face_normal(f))};
}

/// t with its tree of balls, as the engine's template cache makes it for large templates.
vfe::kernels::ParticleTemplate with_tree(vfe::kernels::ParticleTemplate t) {
  t.tree = vfe::kernels::make_point_tree(t.points, t.fractions);
  return t;
}

}  // namespace

TEST(PolyMeshEngine, SubElementSearchMatchesThePointLocator) {
  // Every 10th or 20th particle of the bed (the first ones all lie at the bottom, far from
  // the snappy mesh's tube), whole particles outside the mesh included. The cylinder and
  // snappy meshes take the walks (the cylinder's core is boxes), box_graded the lattice.
  const Particles bed = packed_bed();
  vfe::detail::Scratch s;  // shared by everything, as a thread's is
  for (const char* name : {"cylinder_ogrid_coarse", "snappy_obstacle", "box_graded"}) {
    const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/" + name);
    const vfe::CellLocator locator(mesh);
    SubElementCheck count;
    using vfe::kernels::make_fibonacci_template;
    using vfe::Outside;
    check_sub_elements(mesh, locator, bed, make_fibonacci_template(27), 10, Outside::nearest, s, count);
    check_sub_elements(mesh, locator, bed, make_fibonacci_template(343), 20, Outside::nearest, s, count);
    check_sub_elements(mesh, locator, bed, make_fibonacci_template(8000), 397, Outside::nearest, s, count);
    check_sub_elements(mesh, locator, bed, vfe::kernels::make_spherical_template(125), 20, Outside::drop, s, count);
    check_sub_elements(mesh, locator, bed, vfe::kernels::make_voxel_template(1000), 83, Outside::centre, s, count);
    // The same with the templates' trees of balls (where no lattice serves the particle).
    check_sub_elements(mesh, locator, bed, with_tree(make_fibonacci_template(343)), 20, Outside::nearest, s, count);
    check_sub_elements(mesh, locator, bed, with_tree(make_fibonacci_template(8000)), 397, Outside::nearest, s, count);
    check_sub_elements(mesh, locator, bed, with_tree(vfe::kernels::make_spherical_template(125)), 20, Outside::drop, s,
                       count);
    check_sub_elements(mesh, locator, bed, with_tree(vfe::kernels::make_voxel_template(1000)), 83, Outside::centre, s,
                       count);
    EXPECT_GT(count.particles, 4000) << name;
    EXPECT_GT(count.brute_force, count.points / 62) << name;
    if (std::string(name) != "box_graded") {
      EXPECT_GT(count.outside, count.points / 50) << name;  // the outside policies are exercised
    }
  }
}

TEST(PolyMeshEngine, SubElementSearchMatchesThePointLocatorForBallsGrazingFacePlanes) {
  // The walks leave out the faces whose planes the particle's ball stays below. Balls
  // whose highest point lies within a few 1e-12 of a face's plane (its deep limit, or the
  // plane itself), with a sub-element at that highest point and others just inside it,
  // must still get every sub-element in the locator's cell.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  vfe::detail::Scratch s;
  for (const char* name : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/" + name);
    const vfe::CellLocator locator(mesh);
    SubElementCheck count;
    for (int i = 0; i < 1500; ++i) {
      const auto [c, f, n] = random_cell_face(mesh, rng);
      // Unrotated template: a point on the normal at the ball's top, the rest around it.
      vfe::kernels::ParticleTemplate t;
      t.points = {n, (1 - 1e-13) * n, -n, Eigen::Vector3d::Zero()};
      const Eigen::Vector3d side = n.unitOrthogonal();
      for (const double a : {1e-7, 1e-5, 1e-3}) t.points.push_back(std::sqrt(1 - a * a) * n + a * side);
      t.fractions.assign(t.points.size(), 1.0 / double(t.points.size()));
      for (const Eigen::Vector3d& q : t.points) t.reach = std::max(t.reach, q.norm());
      const double r = 0.2e-3 + 0.4e-3 * u(rng);
      const double base = i % 2 == 0 ? -mesh.face_warp(f) - mesh.location_tolerance() : 0.0;
      // The highest sub-element's height above the plane.
      const double top = base + 1e-12 * double(i % 7 - 3) * (r + 1e-3);
      const Eigen::Vector3d centre = mesh.face_centre(f) + (top - r * t.reach) * n;
      Particles bed;
      bed.centres = {centre.x(), centre.y(), centre.z()};
      bed.radii = {r};
      check_sub_elements(mesh, locator, bed, t, 1, vfe::Outside::nearest, s, count, vfe::Orientation::none);
    }
    EXPECT_EQ(count.particles, 1500) << name;
  }
}

TEST(PolyMeshEngine, SubElementSearchMatchesThePointLocatorForTreeBallsAcrossFacePlanes) {
  // A ball of the template's tree that one cell holds puts all its points there at once.
  // Here a ball's highest point lies within a few 1e-12 of a face's plane or its deep limit
  // (the ball's centre deep in the cell, its top at or beyond the face): every point must
  // still get the locator's cell.
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0, 1);
  vfe::detail::Scratch s;
  const vfe::kernels::ParticleTemplate t = with_tree(vfe::kernels::make_fibonacci_template(2000));
  std::vector<std::size_t> tested;  // the nodes the engine tests against a cell
  for (std::size_t k = 0; k < t.tree.nodes.size(); ++k)
    if (t.tree.nodes[k].count < vfe::detail::kMostPointsTested) tested.push_back(k);
  ASSERT_GT(tested.size(), 20u);
  for (const char* name : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/" + name);
    const vfe::CellLocator locator(mesh);
    SubElementCheck count;
    for (int i = 0; i < 600; ++i) {
      const auto [c, f, n] = random_cell_face(mesh, rng);
      // The template turned so that a node's farthest point from its ball's centre lies
      // straight above that centre along n: the ball's top is that point (turning it keeps
      // every ball holding its points).
      const std::size_t k = tested[static_cast<std::size_t>(i) % tested.size()];
      const vfe::kernels::PointTree::Node& plain = t.tree.nodes[k];
      Eigen::Vector3d far = plain.centre;
      for (std::uint32_t q = plain.first; q < plain.first + plain.count; ++q)
        if ((t.tree.points[q] - plain.centre).norm() > (far - plain.centre).norm()) far = t.tree.points[q];
      const Eigen::Matrix3d turn = Eigen::Quaterniond::FromTwoVectors(far - plain.centre, n).toRotationMatrix();
      vfe::kernels::ParticleTemplate turned = t;
      for (Eigen::Vector3d& q : turned.points) q = turn * q;
      for (Eigen::Vector3d& q : turned.tree.points) q = turn * q;
      for (vfe::kernels::PointTree::Node& node : turned.tree.nodes) node.centre = turn * node.centre;
      const vfe::kernels::PointTree::Node& node = turned.tree.nodes[k];
      double high = -1e300;
      for (std::uint32_t q = node.first; q < node.first + node.count; ++q)
        high = std::max(high, turned.tree.points[q].dot(n));
      // Particles of a tenth to half a cell across, so that a node's ball fits in the cell.
      const double size = std::cbrt(mesh.cell_volume(c));
      const double r = size * (0.1 + 0.4 * u(rng)) / t.reach;
      const double base = i % 2 == 0 ? -mesh.face_warp(f) - mesh.location_tolerance() : 0.0;
      const double top = base + 1e-12 * double(i % 7 - 3) * (r + size);
      const Eigen::Vector3d along = node.centre - node.centre.dot(n) * n;
      const Eigen::Vector3d centre = mesh.face_centre(f) - r * along + (top - r * high) * n;
      Particles bed;
      bed.centres = {centre.x(), centre.y(), centre.z()};
      bed.radii = {r};
      check_sub_elements(mesh, locator, bed, turned, 1, vfe::Outside::nearest, s, count, vfe::Orientation::none);
    }
    EXPECT_EQ(count.particles, 600) << name;
  }
}

TEST(PolyMeshEngine, SortedHashBoxQueryFindsEveryOverlappingCellOnce) {
  for (const char* name : {"cylinder_ogrid_coarse", "snappy_obstacle"}) {
    const vfe::PolyMesh mesh = vfe::PolyMesh::read(kData + "openfoam/" + name);
    const vfe::SpatialHash hash(mesh);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-0.2, 1.2), size(0, 0.004);
    std::vector<std::int64_t> found, expected;
    for (int trial = 0; trial < 200; ++trial) {
      const Eigen::Vector3d lo(0.02 * u(rng), 0.02 * u(rng), 0.06 * u(rng));
      const Eigen::AlignedBox3d box(lo, lo + Eigen::Vector3d(size(rng), size(rng), size(rng)));
      hash.sorted_cells_in_box(box, found);
      expected.clear();
      for (std::int64_t c = 0; c < mesh.cell_count(); ++c)
        if (mesh.cell_bounds(c).intersects(box)) expected.push_back(c);
      ASSERT_EQ(found, expected) << name << " " << trial;
    }
  }
}

TEST(PolyMeshEngine, FacadeReadsBuffersAndLabelListsAndLocatesPoints) {
  const std::string box = kData + "openfoam/box_uniform_10x10x30";
  const vfe::PolyMeshBuffers b = vfe::read_polymesh_buffers(box);
  vfe::Engine from_folder(vfe::PolyMeshSpec{box}), from_buffers(b.view());
  ASSERT_EQ(from_buffers.cell_count(), 3000);
  std::vector<double> v1(3000), v2(3000);
  from_folder.cell_volumes(v1);
  from_buffers.cell_volumes(v2);
  EXPECT_EQ(v1, v2);
  std::int64_t patch_faces = 0;
  for (const auto& p : b.patches) patch_faces += p.n_faces;
  EXPECT_EQ(patch_faces, static_cast<std::int64_t>(b.owner.size() - b.neighbour.size()));
  // blockMesh numbers the single block's cells i + 10 (j + 10 k) on 2 mm cells from 0.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.1, 1.1);
  std::vector<double> points;
  std::vector<std::int64_t> expected;
  for (int i = 0; i < 500; ++i) {
    const double x[3] = {0.02 * u(rng), 0.02 * u(rng), 0.06 * u(rng)};
    points.insert(points.end(), x, x + 3);
    const bool inside = x[0] >= 0 && x[0] < 0.02 && x[1] >= 0 && x[1] < 0.02 && x[2] >= 0 && x[2] < 0.06;
    const auto index = [&](int d) { return static_cast<std::int64_t>(std::floor(x[d] / 0.002)); };
    expected.push_back(inside ? index(0) + 10 * (index(1) + 10 * index(2)) : -1);
  }
  std::vector<std::int64_t> found(expected.size());
  from_folder.locate(points, found);
  EXPECT_EQ(found, expected);
  EXPECT_THROW(from_folder.locate(points, std::span<std::int64_t>(found).first(3)), vfe::Error);
  // decomposePar's addressing, gzipped: cells in increasing global order, reversed faces negative.
  const std::string proc = kData + "openfoam/decomposed/cylinder_ogrid_coarse_3/processor1";
  const std::vector<std::int64_t> cells = vfe::read_polymesh_labels(proc, "cellProcAddressing");
  const std::vector<std::int64_t> faces = vfe::read_polymesh_labels(proc, "faceProcAddressing");
  EXPECT_EQ(cells.size(), 640u);
  EXPECT_TRUE(std::is_sorted(cells.begin(), cells.end()));
  EXPECT_EQ(faces.size(), vfe::read_polymesh_buffers(proc).owner.size());
  EXPECT_TRUE(std::any_of(faces.begin(), faces.end(), [](std::int64_t f) { return f < 0; }));
  try {
    vfe::read_polymesh_labels(box, "cellProcAddressing");
    ADD_FAILURE() << "an undecomposed case has no cellProcAddressing";
  } catch (const vfe::Error& e) {
    EXPECT_EQ(e.status(), VFE_ERROR_IO);
    EXPECT_NE(std::string(e.what()).find("cellProcAddressing"), std::string::npos) << e.what();
  }
}

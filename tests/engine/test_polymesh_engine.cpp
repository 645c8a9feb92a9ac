// The engine on OpenFOAM polyMeshes: same fields as the Cartesian grid of the same
// cells, conservation on the cylinder and snappyHexMesh meshes with real particles.
#include <vfe/engine.hpp>

#include "particles.hpp"

#include <gtest/gtest.h>

#include <zlib.h>

#include <cmath>
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
    poly.configure(std::string(m) + " deterministic=1");
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
  e.configure("method=gaussian");
  try {
    e.compute(p.view(), f);
    FAIL();
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_UNSUPPORTED);
    EXPECT_NE(std::string(err.what()).find("polyMesh"), std::string::npos) << err.what();
  }
  EXPECT_EQ(f[0], 3.0);
  try {
    vfe::Engine bad(vfe::PolyMeshSpec{kData + "openfoam/no_such_case"});
    FAIL();
  } catch (const vfe::Error& err) {
    EXPECT_EQ(err.status(), VFE_ERROR_IO);
  }
}

// Polyhedral (OpenFOAM polyMesh) scenes: the run driver end to end on the project's
// box_uniform_10x10x30 mesh with a tiny dump, the OpenFOAM field files and the .vtu it
// writes, methods the engine lacks on a polyMesh as skipped rows, and the config errors.
#include "config.hpp"
#include "dump_reader.hpp"
#include "foam_writer.hpp"
#include "run.hpp"
#include "study_cmd.hpp"
#include "test_util.hpp"
#include "vtk_writer.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace vfe::apps;
namespace fs = std::filesystem;

namespace {

const fs::path kSource = VFE_SOURCE_DIR;
const fs::path kBoxCase = kSource / "data" / "openfoam" / "box_uniform_10x10x30";

/// n spheres of radius 0.5-1.2 mm inside the box [0, 20] x [0, 20] x [0, 60] mm, one of
/// them centred on a cell corner (x = y = 10 mm, z = 30 mm) so it spans eight cells.
std::string tiny_dump(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::ostringstream o;
  o.precision(12);
  o << "ITEM: TIMESTEP\n500\nITEM: NUMBER OF ATOMS\n" << n
    << "\nITEM: BOX BOUNDS ff ff ff\n0 0.02\n0 0.02\n0 0.06\nITEM: ATOMS id type x y z radius\n";
  o << "1 1 0.01 0.01 0.03 0.0011\n";
  const double len[3] = {0.02, 0.02, 0.06};
  for (int i = 1; i < n; ++i) {
    const double r = 0.0005 + 0.0007 * u(rng);
    o << i + 1 << " 1";
    for (int d = 0; d < 3; ++d) o << ' ' << r + (len[d] - 2 * r) * u(rng);
    o << ' ' << r << '\n';
  }
  return o.str();
}

/// An OpenFOAM volScalarField as written: header entries, the internalField values and the
/// boundaryField text.
struct FoamField {
  std::map<std::string, std::string> header;
  std::string dimensions;
  std::vector<double> values;
  std::int64_t count = -1;
  std::string boundary;
};

FoamField parse_foam_field(const fs::path& file) {
  const std::string text = test::read_text(file);
  FoamField f;
  const auto h0 = text.find("FoamFile");
  const auto hb = text.find('{', h0), he = text.find('}', hb);
  if (h0 == std::string::npos || hb == std::string::npos || he == std::string::npos)
    throw std::runtime_error(file.string() + ": no FoamFile header");
  std::istringstream hs(text.substr(hb + 1, he - hb - 1));
  std::string line;
  while (std::getline(hs, line)) {
    std::istringstream ls(line);
    std::string key, value;
    if (!(ls >> key)) continue;
    std::getline(ls, value);
    value = value.substr(value.find_first_not_of(' '));
    if (!value.empty() && value.back() == ';') value.pop_back();
    f.header[key] = value;
  }
  const auto d = text.find("dimensions", he);
  f.dimensions = text.substr(text.find('[', d), text.find(']', d) - text.find('[', d) + 1);
  const auto i = text.find("internalField", he);
  const std::string kind = "nonuniform List<scalar>";
  if (text.compare(text.find_first_not_of(' ', i + 13), kind.size(), kind) != 0)
    throw std::runtime_error(file.string() + ": internalField is not a nonuniform List<scalar>");
  std::istringstream vs(text.substr(i + 13 + text.substr(i + 13).find(kind) + kind.size()));
  std::string tok;
  vs >> f.count >> tok;
  if (tok != "(") throw std::runtime_error(file.string() + ": no '(' after the count");
  while (vs >> tok && tok != ")") f.values.push_back(std::stod(tok));
  vs >> tok;
  if (tok != ";") throw std::runtime_error(file.string() + ": no ';' after the list");
  f.boundary = text.substr(text.find("boundaryField", i));
  return f;
}

/// The text of the DataArray Name="name" of an ASCII VTK XML file, split into numbers.
std::vector<double> vtk_ascii_array(const std::string& xml, const std::string& name) {
  const auto at = xml.find("Name=\"" + name + "\"");
  if (at == std::string::npos) throw std::runtime_error("no DataArray " + name);
  const auto b = xml.find('>', at) + 1, e = xml.find("</DataArray>", b);
  std::istringstream in(xml.substr(b, e - b));
  std::vector<double> v;
  double x;
  while (in >> x) v.push_back(x);
  return v;
}

std::string polymesh_config(const std::string& mesh_entries) {
  return "name: poly\n"
         "particles:\n  file: data/tiny.dump.gz\n"
         "meshes:\n" +
         mesh_entries +
         "methods:\n"
         "  - direct\n"
         "  - pmm\n"
         "  - {method: pmm, options: \"particle_grid=27\", label: pmm_27}\n"
         "  - exact\n"
         "  - trilinear\n"
         "reference: {method: pmm, options: \"particle_grid=1000\", label: pmm_ref}\n"
         "threads: 1\n"
         "repeats: 1\n"
         "options: \"outside=nearest\"\n"
         "output: out\n";
}

struct PolyScene {
  test::TempDir dir;
  fs::path config;
  explicit PolyScene(const std::string& mesh_entries, int n = 12) {
    fs::create_directories(dir / "data");
    test::write_gzip(dir / "data" / "tiny.dump.gz", tiny_dump(n, 11));
    config = dir / "poly.yaml";
    test::write_text(config, polymesh_config(mesh_entries));
  }
};

}  // namespace

TEST(PolyMeshRun, BoxUniformEndToEnd) {
  // The case folder by a path relative to the config, the polyMesh folder by an absolute path.
  PolyScene scene("");
  const std::string rel = fs::relative(kBoxCase, fs::weakly_canonical(scene.dir.path())).string();
  test::write_text(scene.config, polymesh_config("  - {name: box, type: polymesh, path: " + rel + "}\n" +
                                                 "  - {name: box_pm, type: polymesh, path: " +
                                                 (kBoxCase / "constant" / "polyMesh").string() + "}\n"));
  const SceneConfig cfg = load_config(scene.config);
  ASSERT_EQ(cfg.meshes.size(), 2u);
  EXPECT_EQ(cfg.meshes[0].type, "polymesh");
  EXPECT_EQ(find_polymesh_folder(cfg.meshes[0].path), find_polymesh_folder(kBoxCase));

  std::ostringstream table;
  RunOptions opt;
  opt.table = &table;
  opt.vtk = true;
  opt.foam = true;
  const RunResult res = run_scene(cfg, opt);

  // 2 meshes x (5 methods + the reference, which is not one of them).
  ASSERT_EQ(res.rows.size(), 12u);
  const fs::path csv = res.output / "results.csv";
  ASSERT_TRUE(fs::exists(csv));
  const auto rows = test::read_csv(csv);
  ASSERT_EQ(rows.size(), 12u);
  for (const auto& row : rows) {
    SCOPED_TRACE(row.at("mesh") + " / " + row.at("method"));
    EXPECT_EQ(row.at("mesh_type"), "polymesh");
    EXPECT_EQ(row.at("cells"), "3000");
    EXPECT_EQ(row.at("nx"), "");
    EXPECT_EQ(row.at("particles"), "12");
    const std::string m = row.at("method");
    if (m == "trilinear") {  // not available on a polyMesh: a skipped row with the reason
      EXPECT_EQ(row.at("status"), "skipped");
      EXPECT_NE(row.at("note").find("polyMesh"), std::string::npos) << row.at("note");
      continue;
    }
    EXPECT_EQ(row.at("status"), "ok");
    EXPECT_LT(std::stod(row.at("volume_error")), 1e-9);
    EXPECT_GT(std::stod(row.at("time_median_ms")), 0.0);
    const double chi = std::stod(row.at("chi"));
    EXPECT_GT(chi, 0.8);
    EXPECT_LT(chi, 2.5);
    EXPECT_EQ(row.at("reference"), m == "pmm_ref" ? "1" : "0");
    if (m == "pmm_ref") {
      EXPECT_LT(std::stod(row.at("theta")), 1e-12);
    }
    if (m == "pmm_27") {
      EXPECT_EQ(row.at("particle_grid_min"), "27");
    }
  }

  // The table says the cell size is a mean, names the reference and the skipped method.
  const std::string t = table.str();
  for (const char* s : {"mesh box:", "polyMesh of 3000 cells", "mean chi", "reference pmm_ref (pmm particle_grid=1000)",
                        "pmm_ref *", "trilinear skipped:"})
    EXPECT_NE(t.find(s), std::string::npos) << s << "\n" << t;

  // The OpenFOAM fields: one per method, and plain voidfraction = the default method (pmm).
  vfe::Engine engine(vfe::PolyMeshSpec{kBoxCase.string()});
  const DumpFrame frame = read_dump_frame((scene.dir / "data" / "tiny.dump.gz").string(), FrameSelector{-1});
  std::vector<double> solid(3000), eps(3000);
  for (const std::string mesh : {"box", "box_pm"}) {
    const fs::path time_dir = res.output / mesh / "0";
    for (const std::string label : {"direct", "pmm", "pmm_27", "exact", "pmm_ref"}) {
      SCOPED_TRACE(mesh + " / " + label);
      const fs::path file = time_dir / ("voidfraction_" + label);
      ASSERT_TRUE(fs::exists(file));
      const FoamField f = parse_foam_field(file);
      EXPECT_EQ(f.header.at("class"), "volScalarField");
      EXPECT_EQ(f.header.at("object"), "voidfraction_" + label);
      EXPECT_EQ(f.header.at("format"), "ascii");
      EXPECT_EQ(f.dimensions, "[0 0 0 0 0 0 0]");
      EXPECT_EQ(f.count, 3000);
      ASSERT_EQ(f.values.size(), 3000u);
      EXPECT_NE(f.boundary.find("\".*\""), std::string::npos);
      EXPECT_NE(f.boundary.find("zeroGradient"), std::string::npos);
      // The values are the engine's void fraction with the row's options.
      const auto row = std::find_if(res.rows.begin(), res.rows.end(),
                                    [&](const ResultRow& r) { return r.mesh == mesh && r.label == label; });
      ASSERT_NE(row, res.rows.end());
      engine.configure(row->options);
      engine.compute(frame.view(), solid);
      engine.void_fraction(eps);
      double max_diff = 0, min_eps = 1;
      for (std::size_t c = 0; c < eps.size(); ++c) {
        max_diff = std::max(max_diff, std::abs(f.values[c] - eps[c]));
        min_eps = std::min(min_eps, f.values[c]);
      }
      EXPECT_LT(max_diff, 1e-12);
      EXPECT_LT(min_eps, 0.95);  // the particles are there
    }
    EXPECT_FALSE(fs::exists(time_dir / "voidfraction_trilinear"));
    const FoamField plain = parse_foam_field(time_dir / "voidfraction");
    EXPECT_EQ(plain.header.at("object"), "voidfraction");
    EXPECT_EQ(plain.values, parse_foam_field(time_dir / "voidfraction_pmm").values);
  }

  // The .vtu: 3000 polyhedra with the fields of the methods that ran.
  for (const std::string mesh : {"box", "box_pm"}) {
    const fs::path vtu = res.output / (mesh + ".vtu");
    ASSERT_TRUE(fs::exists(vtu));
    const std::string xml = test::read_text(vtu);
    EXPECT_NE(xml.find("type=\"UnstructuredGrid\""), std::string::npos);
    EXPECT_NE(xml.find("NumberOfCells=\"3000\""), std::string::npos);
    EXPECT_NE(xml.find("NumberOfPoints=\"3751\""), std::string::npos);
    for (const char* name :
         {"voidfraction_pmm", "solid_volume_pmm", "voidfraction_pmm_ref", "voidfraction_exact", "faces", "faceoffsets"})
      EXPECT_NE(xml.find("Name=\"" + std::string(name) + "\""), std::string::npos) << name;
    EXPECT_EQ(xml.find("voidfraction_trilinear"), std::string::npos);
  }
}

TEST(PolyMeshRun, VtuCellsArePolyhedraWithOutwardFaces) {
  vfe::Engine engine(vfe::PolyMeshSpec{kBoxCase.string()});
  const auto n = engine.cell_count();
  ASSERT_EQ(n, 3000);
  std::vector<double> centres(3 * n), volume(n);
  engine.cell_centres(centres);
  engine.cell_volumes(volume);
  const vfe::Engine::PolyTopology topo = engine.poly_topology();
  test::TempDir dir;
  write_vtu(dir / "box.vtu", topo, centres, {{"volume", volume}}, VtkEncoding::ascii);
  const std::string xml = test::read_text(dir / "box.vtu");

  const auto types = vtk_ascii_array(xml, "types");
  ASSERT_EQ(types.size(), 3000u);
  for (double t : types) ASSERT_EQ(t, 42.0);
  const auto offsets = vtk_ascii_array(xml, "offsets");
  const auto faceoffsets = vtk_ascii_array(xml, "faceoffsets");
  const auto faces = vtk_ascii_array(xml, "faces");
  const auto points = vtk_ascii_array(xml, "Points");
  ASSERT_EQ(offsets.size(), 3000u);
  ASSERT_EQ(faceoffsets.size(), 3000u);
  EXPECT_EQ(offsets.back(), 3000.0 * 8);  // hexahedra: 8 points each
  ASSERT_EQ(static_cast<std::size_t>(faceoffsets.back()), faces.size());
  EXPECT_EQ(vtk_ascii_array(xml, "volume"), volume);

  // Volume by the divergence theorem from the written faces: V = sum over faces of
  // (area vector . face point) / 3, which is the cell volume only if every face points out.
  std::size_t k = 0;
  for (std::int64_t c = 0; c < n; ++c) {
    const auto nf = static_cast<std::int64_t>(faces[k++]);
    ASSERT_EQ(nf, 6);
    double v = 0;
    for (std::int64_t f = 0; f < nf; ++f) {
      const auto np = static_cast<std::size_t>(faces[k++]);
      std::array<double, 3> area{0, 0, 0};
      const double* p0 = &points[3 * static_cast<std::size_t>(faces[k])];
      for (std::size_t i = 0; i < np; ++i) {
        const double* p = &points[3 * static_cast<std::size_t>(faces[k + i])];
        const double* q = &points[3 * static_cast<std::size_t>(faces[k + (i + 1) % np])];
        area[0] += 0.5 * (p[1] * q[2] - p[2] * q[1]);
        area[1] += 0.5 * (p[2] * q[0] - p[0] * q[2]);
        area[2] += 0.5 * (p[0] * q[1] - p[1] * q[0]);
      }
      v += (area[0] * p0[0] + area[1] * p0[1] + area[2] * p0[2]) / 3.0;
      k += np;
    }
    ASSERT_EQ(static_cast<double>(k), faceoffsets[static_cast<std::size_t>(c)]);
    ASSERT_NEAR(v, volume[static_cast<std::size_t>(c)], 1e-9 * volume[static_cast<std::size_t>(c)]) << "cell " << c;
  }
}

TEST(PolyMeshRun, FoamFieldKeepsConstraintPatches) {
  test::TempDir dir;
  EXPECT_TRUE(read_constraint_patches(find_polymesh_folder(kBoxCase)).empty());  // patch and wall only
  fs::create_directories(dir / "polyMesh");
  test::write_text(dir / "polyMesh" / "boundary",
                   "FoamFile\n{\n    class polyBoundaryMesh;\n    object boundary;\n}\n// comment\n3\n(\n"
                   "    front { type empty; inGroups 1(empty); nFaces 10; startFace 5; }\n"
                   "    wall /* the wall */ { type wall; nFaces 4; startFace 15; }\n"
                   "    axis\n    {\n        type wedge;\n        nFaces 2;\n        startFace 19;\n    }\n)\n");
  const auto patches = read_constraint_patches(dir / "polyMesh");
  ASSERT_EQ(patches.size(), 2u);
  EXPECT_EQ(patches[0].name, "front");
  EXPECT_EQ(patches[0].type, "empty");
  EXPECT_EQ(patches[1].name, "axis");
  EXPECT_EQ(patches[1].type, "wedge");

  const std::vector<double> values{0.25, 1, 0.5};
  write_foam_scalar_field(dir / "0" / "voidfraction", "voidfraction", "0", values, patches);
  const FoamField f = parse_foam_field(dir / "0" / "voidfraction");
  EXPECT_EQ(f.count, 3);
  EXPECT_EQ(f.values, values);
  EXPECT_NE(f.boundary.find("front\n    {\n        type            empty;"), std::string::npos) << f.boundary;
  EXPECT_NE(f.boundary.find("type            wedge;"), std::string::npos) << f.boundary;
}

TEST(PolyMeshConfig, ParsesAndResolvesThePath) {
  const SceneConfig c = parse_config(
      "particles: p.dump\nmeshes:\n  - {name: cyl, type: polymesh, path: ../data/openfoam/cyl}\nmethods: [pmm]\n",
      "/cfg/configs", "s.yaml");
  ASSERT_EQ(c.meshes.size(), 1u);
  EXPECT_EQ(c.meshes[0].type, "polymesh");
  EXPECT_EQ(c.meshes[0].path, fs::path("/cfg/data/openfoam/cyl"));
  EXPECT_FALSE(c.foam);
  EXPECT_TRUE(parse_config("particles: p\nmeshes: [{type: polymesh, path: m}]\nmethods: [pmm]\nfoam: true\n", "/a",
                           "s.yaml")
                  .foam);
}

TEST(PolyMeshConfig, ClearErrors) {
  auto error_of = [](const std::string& text) {
    try {
      (void)parse_config(text, "/cfg", "scene.yaml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string head = "particles: p.dump\nmethods: [pmm]\nmeshes:\n";
  std::string msg = error_of(head + "  - {name: m, type: tetgen, path: x}\n");
  EXPECT_NE(msg.find("scene.yaml:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown mesh type 'tetgen'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("polymesh"), std::string::npos) << msg;  // says what is allowed

  msg = error_of(head + "  - {name: m, type: polymesh}\n");
  EXPECT_NE(msg.find("mesh 'm'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("needs 'path"), std::string::npos) << msg;

  msg = error_of(head + "  - {name: m, type: polymesh, path: x, spacing: 0.002}\n");
  EXPECT_NE(msg.find("unknown key 'spacing'"), std::string::npos) << msg;

  msg = error_of(head + "  - {name: m, type: cartesian, path: x, origin: 0, spacing: 1, cells: 2}\n");
  EXPECT_NE(msg.find("unknown key 'path'"), std::string::npos) << msg;
}

TEST(PolyMeshConfig, MissingPolyMeshFailsBeforeAnyWork) {
  {
    PolyScene scene("  - {name: box, type: polymesh, path: cases/none}\n");
    try {
      (void)run_scene(load_config(scene.config), RunOptions{});
      FAIL() << "no error";
    } catch (const ConfigError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("poly.yaml:5"), std::string::npos) << msg;
      EXPECT_NE(msg.find("mesh 'box'"), std::string::npos) << msg;
      EXPECT_NE(msg.find("cases/none"), std::string::npos) << msg;
      EXPECT_NE(msg.find("does not exist"), std::string::npos) << msg;
    }
    EXPECT_FALSE(fs::exists(scene.dir / "out"));
  }
  {
    // A folder without a polyMesh (the case's system folder).
    PolyScene scene("  - {name: box, type: polymesh, path: " + (kBoxCase / "system").string() + "}\n");
    try {
      (void)run_scene(load_config(scene.config), RunOptions{});
      FAIL() << "no error";
    } catch (const ConfigError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("no polyMesh in"), std::string::npos) << msg;
      EXPECT_NE(msg.find("constant/polyMesh"), std::string::npos) << msg;
    }
    EXPECT_FALSE(fs::exists(scene.dir / "out"));
  }
}

TEST(PolyMeshStudy, EveryMeshKindWithChiFromTheMeanCubeRoot) {
  // The same 10 x 10 x 30 cells of 2 mm as a polyMesh, a Cartesian grid and a rectilinear
  // grid, and the graded box polyMesh (cells of unequal volume).
  const fs::path graded = kSource / "data" / "openfoam" / "box_graded";
  PolyScene scene("", 40);
  test::write_text(scene.config,
                   "name: poly_study\n"
                   "particles:\n  file: data/tiny.dump.gz\n"
                   "meshes:\n"
                   "  - {name: box, type: polymesh, path: " + kBoxCase.string() + "}\n"
                   "  - {name: grid, origin: [0, 0, 0], spacing: [0.002, 0.002, 0.002], cells: [10, 10, 30]}\n"
                   "  - {name: rect, type: rectilinear, x: {lo: 0, hi: 0.02, cells: 10}, y: {lo: 0, hi: 0.02, "
                   "cells: 10}, z: {lo: 0, hi: 0.06, cells: 30}}\n"
                   "  - {name: graded, type: polymesh, path: " + graded.string() + "}\n"
                   "methods:\n"
                   "  - direct\n"
                   "  - {method: pmm, settings: [\"particle_grid=5\", \"particle_grid=40\"]}\n"
                   "  - {method: gaussian, settings: [\"sigma=0.25\"]}\n"
                   "  - porous_cube\n"
                   "  - trilinear\n"
                   "  - exact\n"
                   "reference: exact\n"
                   "threads: 1\n"
                   "repeats: 1\n"
                   // The part of a kernel beyond the wall goes to the particle's own cell, the
                   // same cell on every mesh kind (nearest may pick another one at a corner).
                   "options: \"outside=centre\"\n"
                   "output: out\n");
  std::ostringstream table;
  StudyOptions opt;
  opt.table = &table;
  const StudyResult res = run_study(load_config(scene.config), opt);
  ASSERT_EQ(res.points.size(), 4u * 7u);

  const DumpFrame frame = read_dump_frame((scene.dir / "data" / "tiny.dump.gz").string(), FrameSelector{-1});
  double mean_d = 0;
  for (double r : frame.radii) mean_d += 2 * r;
  mean_d /= static_cast<double>(frame.radii.size());
  // The graded mesh's chi: the mean over its cells of the cube root of the cell volume.
  vfe::Engine graded_engine(vfe::PolyMeshSpec{graded.string()});
  std::vector<double> volumes(static_cast<std::size_t>(graded_engine.cell_count()));
  graded_engine.cell_volumes(volumes);
  double mean_root = 0, mean_volume = 0;
  for (double v : volumes) {
    mean_root += std::cbrt(v) / static_cast<double>(volumes.size());
    mean_volume += v / static_cast<double>(volumes.size());
  }
  ASSERT_GT(std::cbrt(mean_volume) - mean_root, 1e-3 * mean_root);  // the two means differ here

  auto point = [&](const std::string& mesh, const std::string& family, const std::string& setting) {
    const auto it = std::find_if(res.points.begin(), res.points.end(), [&](const StudyPoint& p) {
      return p.mesh == mesh && p.family == family && p.setting == setting;
    });
    if (it == res.points.end()) throw std::logic_error("no point " + mesh + " " + family + " " + setting);
    return *it;
  };
  for (const StudyPoint& p : res.points) {
    SCOPED_TRACE(p.mesh + " " + p.family + " " + p.setting);
    EXPECT_NEAR(p.chi, p.mesh == "graded" ? mean_root / mean_d : 0.002 / mean_d, 1e-9 * p.chi);
    EXPECT_EQ(p.mesh_type, p.mesh == "grid" ? "cartesian" : p.mesh == "rect" ? "rectilinear" : "polymesh");
    EXPECT_EQ(p.particles, 40);
    if (p.family == "trilinear" && p.mesh_type == "polymesh") {  // refused at configure: skipped
      EXPECT_TRUE(p.skipped);
      EXPECT_FALSE(p.pareto);
      EXPECT_TRUE(std::isnan(p.time_median_ms));
      EXPECT_NE(p.note.find("polyMesh"), std::string::npos) << p.note;
      continue;
    }
    EXPECT_FALSE(p.skipped);
    EXPECT_GT(p.time_median_ms, 0.0);
    EXPECT_LT(p.accuracy.volume_error, 1e-9);
    if (p.family == "exact") {
      EXPECT_LT(p.accuracy.l1, 1e-12);
      EXPECT_TRUE(p.pareto);
    } else {
      EXPECT_GT(p.accuracy.l1, 1e-4);
    }
    if (p.mesh == "box" || p.mesh == "rect") {
      // Same cells as the Cartesian grid: the same errors against exact.
      const StudyPoint c = point("grid", p.family, p.setting);
      EXPECT_NEAR(p.accuracy.l1, c.accuracy.l1, 1e-9);
      EXPECT_NEAR(p.accuracy.theta, c.accuracy.theta, 1e-9);
      EXPECT_EQ(p.grid, (p.mesh == "box" ? std::array<std::int64_t, 3>{0, 0, 0} : c.grid));
    }
  }
  // The skipped points are in the files with their reason, and compared with nothing.
  for (const auto& c : res.comparisons) EXPECT_FALSE((c.mesh == "box" || c.mesh == "graded") && c.family == "trilinear");
  bool skipped_row = false;
  for (const auto& row : test::read_csv(res.output / "study.csv")) {
    if (row.at("mesh") == "box" && row.at("family") == "trilinear") {
      EXPECT_EQ(row.at("status"), "skipped");
      EXPECT_EQ(row.at("mesh_type"), "polymesh");
      EXPECT_EQ(row.at("cells"), "3000");
      skipped_row = true;
    }
  }
  EXPECT_TRUE(skipped_row);
  const std::string t = table.str();
  for (const char* s : {"mesh box: polyMesh of 3000 cells, mean cube root of the cell volume 0.002",
                        "mesh rect: rectilinear grid of 3000 cells", "mesh grid: 10 x 10 x 30 cells",
                        "skipped: "})
    EXPECT_NE(t.find(s), std::string::npos) << s << "\n" << t;
}

// coupling: true with every particle moving at the same velocity: Us is that velocity in every
// cell holding solid and 0 elsewhere (OpenFOAM's volVectorField Us and Us_<method>), and each
// particle's weights in <mesh>_weights_<method>.csv sum to 1.
TEST(PolyMeshRun, CouplingFieldsOfAUniformVelocity) {
  const double velocity[3] = {1.5, -2.0, 0.25};
  std::istringstream plain(tiny_dump(12, 11));
  std::ostringstream moving;
  moving.precision(12);
  std::string line;
  bool atoms = false;
  while (std::getline(plain, line)) {
    if (line.rfind("ITEM: ATOMS", 0) == 0) {
      moving << line << " vx vy vz\n";
      atoms = true;
    } else {
      moving << line << (atoms ? " 1.5 -2 0.25\n" : "\n");
    }
  }
  test::TempDir dir;
  fs::create_directories(dir / "data");
  test::write_text(dir / "data" / "moving.dump", moving.str());
  test::write_text(dir / "coupling.yaml", "name: coupling\nparticles:\n  file: data/moving.dump\nmeshes:\n"
                                          "  - {name: box, type: polymesh, path: " +
                                              kBoxCase.string() +
                                              "}\nmethods: [pmm, exact]\nreference: exact\nthreads: 1\n"
                                              "repeats: 1\noutput: out\nfoam: true\ncoupling: true\n");
  RunOptions opt;
  opt.vtk = true;
  const RunResult res = run_scene(load_config(dir / "coupling.yaml"), opt);
  const fs::path time_dir = res.output / "box" / "0";
  EXPECT_NE(test::read_text(res.output / "box.vtu").find("Name=\"Us_exact\" NumberOfComponents=\"3\""),
            std::string::npos);

  for (const std::string label : {"pmm", "exact"}) {
    SCOPED_TRACE(label);
    const std::string us_text = test::read_text(time_dir / ("Us_" + label));
    EXPECT_NE(us_text.find("class       volVectorField;"), std::string::npos);
    EXPECT_NE(us_text.find("dimensions      [0 1 -1 0 0 0 0];"), std::string::npos);
    const std::vector<double> us = test::read_foam_vectors(time_dir / ("Us_" + label));
    const FoamField eps = parse_foam_field(time_dir / ("voidfraction_" + label));
    const std::size_t count = eps.values.size();
    ASSERT_EQ(us.size(), 3 * count);
    std::size_t solid_cells = 0;
    for (std::size_t c = 0; c < count; ++c) {
      const bool solid = eps.values[c] < 1.0;
      solid_cells += solid;
      for (int d = 0; d < 3; ++d)
        EXPECT_NEAR(us[3 * c + d], solid ? velocity[d] : 0.0, 1e-12) << "cell " << c << " component " << d;
    }
    EXPECT_GT(solid_cells, 12u);  // the corner particle alone spans eight cells

    std::map<std::int64_t, double> sums;
    for (const auto& row : test::read_csv(res.output / ("box_weights_" + label + ".csv"))) {
      const std::int64_t cell = std::stoll(row.at("cell"));
      EXPECT_GE(cell, 0);
      EXPECT_LT(cell, static_cast<std::int64_t>(count));
      sums[std::stoll(row.at("particle"))] += std::stod(row.at("fraction"));
    }
    ASSERT_EQ(sums.size(), 12u);
    for (const auto& [particle, sum] : sums) EXPECT_NEAR(sum, 1.0, 1e-12) << "particle " << particle;
  }
  // The plain Us beside voidfraction comes from the default method (pmm).
  EXPECT_EQ(test::read_text(time_dir / "Us").substr(test::read_text(time_dir / "Us").find("internalField")),
            test::read_text(time_dir / "Us_pmm").substr(test::read_text(time_dir / "Us_pmm").find("internalField")));
}

// coupling: true on a dump without velocities is refused, naming what is missing.
TEST(PolyMeshRun, CouplingNeedsVelocities) {
  PolyScene scene("  - {name: box, type: polymesh, path: " + kBoxCase.string() + "}\n");
  test::write_text(scene.config, test::read_text(scene.config) + "coupling: true\n");
  try {
    run_scene(load_config(scene.config), RunOptions{});
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("has no vx vy vz columns"), std::string::npos) << e.what();
  }
}

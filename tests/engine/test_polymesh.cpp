// Polyhedral meshes: OpenFOAM polyMesh reader (ASCII, gzip, binary, malformed input),
// OpenFOAM's face/cell geometry, the rectilinear grid, exact point location and its tie
// rule, and the three locators against brute force.
#include "polymesh/locators.hpp"
#include "block_mesh.hpp"
#include "polymesh/polymesh.hpp"
#include "polymesh/polymesh_reader.hpp"
#include "polymesh/predicates.hpp"
#include "polymesh/rectilinear_grid.hpp"

#include <vfe/engine.hpp>

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using vfe::CellLocator;
using vfe::PolyMesh;
using vfe::PolyMeshData;
using vfe::test::block_mesh;
using vfe::test::nodes;

fs::path case_dir(const std::string& name) { return fs::path(VFE_SOURCE_DIR) / "data" / "openfoam" / name; }

/// A mesh and its locators, read once per test program and shared read-only.
struct Loaded {
  PolyMesh mesh;
  std::unique_ptr<CellLocator> locator;
  explicit Loaded(const std::string& name) : mesh(PolyMesh::read(case_dir(name))) {
    locator = std::make_unique<CellLocator>(mesh);
  }
};

const Loaded& loaded(const std::string& name) {
  static std::mutex m;
  static std::map<std::string, std::unique_ptr<Loaded>> cache;
  std::lock_guard<std::mutex> lock(m);
  auto& slot = cache[name];
  if (!slot) slot = std::make_unique<Loaded>(name);
  return *slot;
}

/// A fresh temporary folder, removed at the end of the test.
struct TempDir {
  fs::path path;
  TempDir() {
    static std::atomic<int> counter{0};
    path = fs::temp_directory_path() /
           ("vfe_polymesh_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}
void write_gzip(const fs::path& p, const std::string& text) {
  gzFile gz = gzopen(p.string().c_str(), "wb");
  ASSERT_NE(gz, nullptr);
  ASSERT_EQ(gzwrite(gz, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  ASSERT_EQ(gzclose(gz), Z_OK);
}

const char* const kMeshFiles[] = {"points", "faces", "owner", "neighbour", "boundary"};

// ---------------------------------------------------------------------------------------
// Writers of polyMesh files (as OpenFOAM writes them) for round trips and broken copies.

std::string foam_header(const std::string& cls, const std::string& object, const std::string& format = "ascii",
                        const std::string& extra = "") {
  return "/*--------------------------------*- C++ -*----------------------------------*\\\n"
         "  written by the vfe test suite\n"
         "\\*---------------------------------------------------------------------------*/\n"
         "FoamFile\n{\n    version     2.0;\n    format      " +
         format + ";\n    class       " + cls + ";\n" + extra + "    location    \"constant/polyMesh\";\n    object      " +
         object + ";\n}\n// * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * //\n\n";
}

std::string g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string boundary_text(const PolyMeshData& d, const std::string& format = "ascii") {
  std::string s = foam_header("polyBoundaryMesh", "boundary", format) + std::to_string(d.patches.size()) + "\n(\n";
  for (const auto& p : d.patches)
    s += "    " + p.name + "\n    {\n        type            " + p.type + ";\n        nFaces          " +
         std::to_string(p.n_faces) + ";\n        startFace       " + std::to_string(p.start_face) + ";\n    }\n";
  return s + ")\n\n// ************************************************************************* //\n";
}

/// Writes d in ASCII (faceList, or faceCompactList when compact).
void write_ascii(const fs::path& dir, const PolyMeshData& d, bool compact = false) {
  std::string s = foam_header("vectorField", "points") + std::to_string(d.points.size()) + "\n(\n";
  for (const auto& p : d.points) s += "(" + g17(p.x()) + " " + g17(p.y()) + " " + g17(p.z()) + ")\n";
  write_text(dir / "points", s + ")\n");
  const auto n_faces = d.face_offsets.size() - 1;
  if (compact) {
    s = foam_header("faceCompactList", "faces") + std::to_string(d.face_offsets.size()) + "\n(\n";
    for (const auto o : d.face_offsets) s += std::to_string(o) + "\n";
    s += ")\n\n" + std::to_string(d.face_points.size()) + "\n(\n";
    for (const auto q : d.face_points) s += std::to_string(q) + "\n";
    s += ")\n";
  } else {
    s = foam_header("faceList", "faces") + std::to_string(n_faces) + "\n(\n";
    for (std::size_t f = 0; f < n_faces; ++f) {
      s += std::to_string(d.face_offsets[f + 1] - d.face_offsets[f]) + "(";
      for (auto i = d.face_offsets[f]; i < d.face_offsets[f + 1]; ++i)
      {
        if (i > d.face_offsets[f]) s += ' ';
        s += std::to_string(d.face_points[static_cast<std::size_t>(i)]);
      }
      s += ")\n";
    }
    s += ")\n";
  }
  write_text(dir / "faces", s);
  for (const auto& [name, list] : {std::pair{"owner", &d.owner}, std::pair{"neighbour", &d.neighbour}}) {
    s = foam_header("labelList", name) + std::to_string(list->size()) + "\n(\n";
    for (const auto c : *list) s += std::to_string(c) + "\n";
    write_text(dir / name, s + ")\n");
  }
  write_text(dir / "boundary", boundary_text(d));
}

template <class T>
std::string raw_bytes(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

/// Writes d in OpenFOAM's binary format (little-endian; labels of Label type; faces as a
/// faceCompactList, or as a list of binary label lists when !compact).
template <class Label>
void write_binary(const fs::path& dir, const PolyMeshData& d, bool compact = true) {
  const std::string arch = "    arch        \"LSB;label=" + std::to_string(8 * sizeof(Label)) + ";scalar=64\";\n";
  const auto label_list = [](const auto& v) {
    std::vector<Label> l(v.begin(), v.end());
    return "\n" + std::to_string(l.size()) + "\n(" + raw_bytes(l) + ")";
  };
  std::vector<double> xyz;
  for (const auto& p : d.points) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  write_text(dir / "points", foam_header("vectorField", "points", "binary", arch) + "\n" + std::to_string(d.points.size()) +
                                 "\n(" + raw_bytes(xyz) + ")\n\n// ***** //\n");
  std::string faces;
  if (compact) {
    faces = foam_header("faceCompactList", "faces", "binary", arch) + label_list(d.face_offsets) + label_list(d.face_points);
  } else {
    faces = foam_header("faceList", "faces", "binary", arch) + "\n" + std::to_string(d.face_offsets.size() - 1) + "\n(";
    for (std::size_t f = 0; f + 1 < d.face_offsets.size(); ++f)
      faces += label_list(std::vector<std::int64_t>(d.face_points.begin() + d.face_offsets[f],
                                                    d.face_points.begin() + d.face_offsets[f + 1]));
    faces += "\n)";
  }
  write_text(dir / "faces", faces + "\n");
  write_text(dir / "owner", foam_header("labelList", "owner", "binary", arch) + label_list(d.owner) + "\n");
  write_text(dir / "neighbour", foam_header("labelList", "neighbour", "binary", arch) + label_list(d.neighbour) + "\n");
  write_text(dir / "boundary", boundary_text(d, "binary"));
}

void expect_same_mesh(const PolyMeshData& a, const PolyMeshData& b) {
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) ASSERT_EQ(a.points[i], b.points[i]) << "point " << i;
  EXPECT_EQ(a.face_offsets, b.face_offsets);
  EXPECT_EQ(a.face_points, b.face_points);
  EXPECT_EQ(a.owner, b.owner);
  EXPECT_EQ(a.neighbour, b.neighbour);
  ASSERT_EQ(a.patches.size(), b.patches.size());
  for (std::size_t i = 0; i < a.patches.size(); ++i) {
    EXPECT_EQ(a.patches[i].name, b.patches[i].name);
    EXPECT_EQ(a.patches[i].type, b.patches[i].type);
    EXPECT_EQ(a.patches[i].start_face, b.patches[i].start_face);
    EXPECT_EQ(a.patches[i].n_faces, b.patches[i].n_faces);
  }
}


/// Every cell that claims p (brute force, no early exit).
std::vector<std::int64_t> claiming_cells(const PolyMesh& mesh, const Vector3d& p) {
  std::vector<std::int64_t> cells;
  for (std::int64_t c = 0; c < mesh.cell_count(); ++c)
    if (vfe::cell_contains(mesh, c, p)) cells.push_back(c);
  return cells;
}

/// Runs f and checks that it throws vfe::Error with the status and every fragment.
void expect_error(const std::function<void()>& f, vfe_status status, std::vector<std::string> fragments) {
  try {
    f();
    ADD_FAILURE() << "no error thrown";
  } catch (const vfe::Error& e) {
    EXPECT_EQ(e.status(), status) << e.what();
    for (const auto& frag : fragments)
      EXPECT_NE(std::string(e.what()).find(frag), std::string::npos) << "'" << frag << "' missing in: " << e.what();
  }
}

const std::vector<std::string> kMeshes = {"box_uniform_10x10x30", "box_graded", "cylinder_ogrid_coarse", "snappy_obstacle"};

}  // namespace

// =======================================================================================
// Reader

TEST(PolyMeshReader, ReadsAllFourMeshes) {
  const std::map<std::string, std::array<std::int64_t, 4>> expected = {
      // cells, faces, internal faces, points
      {"box_uniform_10x10x30", {3000, 9700, 8300, 3751}},
      {"box_graded", {10240, 32256, 29184, 11849}},
      {"cylinder_ogrid_coarse", {1920, 6064, 5456, 2263}},
      {"snappy_obstacle", {10640, 35152, 31408, -1}},
  };
  for (const auto& name : kMeshes) {
    const PolyMesh& m = loaded(name).mesh;
    const auto& e = expected.at(name);
    EXPECT_EQ(m.cell_count(), e[0]) << name;
    EXPECT_EQ(m.face_count(), e[1]) << name;
    EXPECT_EQ(m.internal_face_count(), e[2]) << name;
    if (e[3] > 0) {
      EXPECT_EQ(m.point_count(), e[3]) << name;
    }
    std::int64_t boundary = 0;
    for (const auto& p : m.patches()) boundary += p.n_faces;
    EXPECT_EQ(boundary, m.face_count() - m.internal_face_count()) << name;
  }
  const auto& patches = loaded("snappy_obstacle").mesh.patches();
  ASSERT_EQ(patches.size(), 4u);
  EXPECT_EQ(patches[3].name, "tube");
  EXPECT_EQ(patches[3].type, "wall");
  EXPECT_EQ(patches[3].start_face, 33232);
  EXPECT_EQ(patches[3].n_faces, 1920);
  EXPECT_FALSE(patches[3].cyclic);
}

TEST(PolyMeshReader, AcceptsCaseFolderPolyMeshFolderAndConstantFolder) {
  const auto base = case_dir("cylinder_ogrid_coarse");
  const PolyMeshData a = vfe::read_polymesh(base);
  const PolyMeshData b = vfe::read_polymesh(base / "constant" / "polyMesh");
  const PolyMeshData c = vfe::read_polymesh(base / "constant");
  expect_same_mesh(a, b);
  expect_same_mesh(a, c);
}

TEST(PolyMeshReader, RoundTripsAsciiCompactGzipAndBinary) {
  const PolyMeshData ref = vfe::read_polymesh(case_dir("box_uniform_10x10x30"));
  {
    TempDir t;  // faceCompactList in ASCII
    write_ascii(t.path, ref, true);
    expect_same_mesh(ref, vfe::read_polymesh(t.path));
  }
  {
    TempDir t;  // every file gzip-compressed
    for (const char* f : kMeshFiles)
      write_gzip(t.path / (std::string(f) + ".gz"), read_text(case_dir("box_uniform_10x10x30") / "constant" / "polyMesh" / f));
    expect_same_mesh(ref, vfe::read_polymesh(t.path));
  }
  {
    TempDir t;  // binary, 32-bit labels, faces as faceCompactList (as OpenFOAM writes them)
    write_binary<std::int32_t>(t.path, ref);
    expect_same_mesh(ref, vfe::read_polymesh(t.path));
  }
  {
    TempDir t;  // binary, 64-bit labels, faces as a list of lists, compressed
    write_binary<std::int64_t>(t.path, ref, false);
    for (const char* f : kMeshFiles) {
      write_gzip(t.path / (std::string(f) + ".gz"), read_text(t.path / f));
      fs::remove(t.path / f);
    }
    expect_same_mesh(ref, vfe::read_polymesh(t.path));
  }
}

TEST(PolyMeshReader, ReadsAsciiVariants) {
  // Comments anywhere, lists without counts, uniform lists, entries split over lines,
  // CRLF line ends, '+' signs and exponents: two unit cubes along x.
  const PolyMeshData ref = block_mesh({nodes(2, 0, 2), nodes(1, 0, 1), nodes(1, 0, 1)});
  TempDir t;
  write_ascii(t.path, ref);
  std::string points = "FoamFile { format ascii; class vectorField; object points; } /* block\ncomment */\n12 // count\n(\n";
  for (std::size_t i = 0; i < ref.points.size(); ++i) {
    const auto& p = ref.points[i];
    points += i % 2 ? "( " + g17(p.x()) + "\r\n " + g17(p.y()) + " // y\n" + g17(p.z()) + " )\r\n"
                    : "(+" + g17(p.x()) + "e0 " + g17(p.y()) + "E+00 " + g17(p.z()) + ")";
  }
  write_text(t.path / "points", points + ")\n// end\n");
  std::string faces = read_text(t.path / "faces");
  faces.replace(faces.find("11\n("), 4, "/* no count */ (");
  write_text(t.path / "faces", faces);
  // owner: 11 faces, owners 0 0 0 0 0 1 1 1 1 1 (block_mesh order) -> a uniform list can't
  // express it, but the neighbour list (one internal face) can.
  ASSERT_EQ(ref.neighbour, std::vector<std::int64_t>{1});
  write_text(t.path / "neighbour", foam_header("labelList", "neighbour") + "1{1}\n");
  const PolyMeshData got = vfe::read_polymesh(t.path);
  expect_same_mesh(ref, got);
  EXPECT_NO_THROW(PolyMesh{got});
}

TEST(PolyMeshReader, MalformedInputGivesClearErrors) {
  const PolyMeshData small = block_mesh({nodes(2, 0, 2), nodes(1, 0, 1), nodes(1, 0, 1)});
  // Each case writes a good copy, breaks one file and checks the error.
  const auto check = [&](const std::string& label, const std::function<void(const fs::path&)>& breaker, vfe_status status,
                         std::vector<std::string> fragments) {
    SCOPED_TRACE(label);
    TempDir t;
    write_ascii(t.path, small);
    ASSERT_NO_THROW(vfe::read_polymesh(t.path));
    breaker(t.path);
    expect_error([&] { PolyMesh::read(t.path); }, status, fragments);
  };
  const auto edit = [](const fs::path& file, const std::string& from, const std::string& to) {
    std::string s = read_text(file);
    const auto at = s.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    s.replace(at, from.size(), to);
    write_text(file, s);
  };
  // foam_header writes 13 lines: the list count is on line 14, its first entry on line 16.
  check("missing file", [](const fs::path& d) { fs::remove(d / "neighbour"); }, VFE_ERROR_IO,
        {"neighbour", "not found", "blockMesh"});
  expect_error([] { vfe::read_polymesh("/nonexistent/vfe/case"); }, VFE_ERROR_IO, {"/nonexistent/vfe/case", "does not exist"});
  check("truncated faces", [](const fs::path& d) { const auto s = read_text(d / "faces");
          write_text(d / "faces", s.substr(0, s.size() - 30)); },
        VFE_ERROR_INVALID_ARGUMENT, {"faces", "line", "truncated"});
  check("wrong count", [&](const fs::path& d) { edit(d / "faces", "\n11\n(", "\n12\n("); }, VFE_ERROR_INVALID_ARGUMENT,
        {"faces", "line 27", "11 faces but its count says 12"});
  check("face with a missing point", [&](const fs::path& d) { edit(d / "faces", "4(1 4 10 7)", "4(1 4 10 12)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"faces", "line 16", "face 0 refers to point 12", "12 points"});
  check("owner shorter than faces", [&](const fs::path& d) { edit(d / "owner", "\n11\n(\n0\n", "\n10\n(\n"); },
        VFE_ERROR_INVALID_ARGUMENT, {"owner", "10 entries", "11 faces"});
  check("garbage token", [&](const fs::path& d) { edit(d / "points", "(1 0 0)", "(1 zero 0)"); }, VFE_ERROR_INVALID_ARGUMENT,
        {"points", "line 17", "expected a number for the y coordinate of point 1", "'zero'"});
  check("point with 2 coordinates", [&](const fs::path& d) { edit(d / "points", "(1 0 0)", "(1 0)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"points", "line 17", "point 1"});
  check("non-finite coordinate", [&](const fs::path& d) { edit(d / "points", "(1 0 0)", "(1 nan 0)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"points", "not a finite number"});
  check("cell count inconsistent with the header note",
        [&](const fs::path& d) {
          edit(d / "owner", "    class       labelList;\n",
               "    class       labelList;\n    note        \"nPoints:12 nCells:3 nFaces:11 nInternalFaces:1\";\n");
        },
        VFE_ERROR_INVALID_ARGUMENT, {"owner", "nCells:3", "2 cells"});
  check("cell label skipped", [&](const fs::path& d) { edit(d / "neighbour", "\n1\n(\n1\n)", "\n1\n(\n2\n)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"cell 2 has 1 faces", "do not match"});
  check("neighbour equals owner", [&](const fs::path& d) { edit(d / "neighbour", "\n1\n(\n1\n)", "\n1\n(\n0\n)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"neighbour", "face 0 has cell 0 as both owner and neighbour"});
  check("patch start wrong", [&](const fs::path& d) { edit(d / "boundary", "startFace       1;", "startFace       2;"); },
        VFE_ERROR_INVALID_ARGUMENT, {"boundary", "patch 'walls' starts at face 2", "1 internal faces"});
  check("unterminated comment", [&](const fs::path& d) { edit(d / "owner", "\n11\n(", "\n11 /* oops\n("); },
        VFE_ERROR_INVALID_ARGUMENT, {"owner", "line 14", "never closed"});
  check("text after the list", [&](const fs::path& d) { write_text(d / "owner", read_text(d / "owner") + "extra\n"); },
        VFE_ERROR_INVALID_ARGUMENT, {"owner", "unexpected 'extra'"});
  check("inverted face (cell not closed)", [&](const fs::path& d) { edit(d / "faces", "4(1 4 10 7)", "4(7 10 4 1)"); },
        VFE_ERROR_INVALID_ARGUMENT, {"cell 0 is not closed", "checkMesh"});
  check("corrupt gzip",
        [&](const fs::path& d) {
          fs::remove(d / "points");
          write_text(d / "points.gz", std::string("\x1f\x8b\x08\x00garbage", 11));
        },
        VFE_ERROR_IO, {"points.gz", "decompress"});
  check("truncated binary",
        [&](const fs::path& d) {
          write_binary<std::int32_t>(d, small);
          const std::string s = read_text(d / "points");
          write_text(d / "points", s.substr(0, s.size() - 40));
        },
        VFE_ERROR_INVALID_ARGUMENT, {"points", "byte", "truncated"});
  check("big-endian binary",
        [&](const fs::path& d) {
          write_binary<std::int32_t>(d, small);
          edit(d / "points", "LSB", "MSB");
        },
        VFE_ERROR_UNSUPPORTED, {"points", "big-endian", "foamFormatConvert -constant"});
}

// =======================================================================================
// Geometry

TEST(PolyMeshGeometry, BoxVolumesSumToTheBoundingBox) {
  for (const std::string name : {"box_uniform_10x10x30", "box_graded"}) {
    const PolyMesh& m = loaded(name).mesh;
    const double box = m.bounds().volume();
    EXPECT_NEAR(box, 0.02 * 0.02 * 0.06, 1e-18) << name;
    EXPECT_NEAR(m.total_volume(), box, 1e-12 * box) << name;
    double sum = 0;
    for (const double v : m.cell_volumes()) sum += v;
    EXPECT_NEAR(sum, box, 1e-12 * box) << name;
  }
  const auto v = loaded("box_graded").mesh.cell_volumes();
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  EXPECT_NEAR(*lo, 2.6e-10, 0.05e-10);  // the README's range of the graded cells
  EXPECT_NEAR(*hi, 1.3e-8, 0.05e-8);
}

TEST(PolyMeshGeometry, BoxUniformCellsAreTwoMillimetreCubesInXFastestOrder) {
  const PolyMesh& m = loaded("box_uniform_10x10x30").mesh;
  // blockMesh numbers cells x fastest: cell 0's neighbours are 1 (+x), 10 (+y), 100 (+z).
  std::set<std::int64_t> n0;
  for (const auto f : m.cell_faces(0))
    if (m.neighbour(f) >= 0) n0.insert(m.across(f, 0));
  EXPECT_EQ(n0, (std::set<std::int64_t>{1, 10, 100}));
  const double h = 0.002;
  for (std::int64_t k = 0; k < 30; ++k)
    for (std::int64_t j = 0; j < 10; ++j)
      for (std::int64_t i = 0; i < 10; ++i) {
        const std::int64_t c = i + 10 * (j + 10 * k);
        ASSERT_NEAR(m.cell_volume(c), h * h * h, 1e-12 * h * h * h) << c;
        const Vector3d expected((i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h);
        ASSERT_LE((m.cell_centre(c) - expected).norm(), 1e-15) << c;
        ASSERT_EQ(m.cell_faces(c).size(), 6u);
      }
}

TEST(PolyMeshGeometry, CylinderVolumeIsThe16GonPrism) {
  const PolyMesh& m = loaded("cylinder_ogrid_coarse").mesh;
  const double r = 0.010, h = 0.060;
  const double prism = 0.5 * 16 * r * r * std::sin(2 * std::numbers::pi / 16) * h;
  EXPECT_NEAR(m.total_volume(), prism, 1e-8 * prism);  // the points are written with 10 digits
  // The README's figure: 2.55 % less than the true cylinder.
  EXPECT_NEAR(1 - m.total_volume() / (std::numbers::pi * r * r * h), 0.0255, 0.0001);
  // Centroid on the axis, half way up.
  Vector3d c = Vector3d::Zero();
  for (std::int64_t i = 0; i < m.cell_count(); ++i) c += m.cell_volume(i) * m.cell_centre(i);
  c /= m.total_volume();
  EXPECT_LE((c - Vector3d(0.01, 0.01, 0.03)).norm(), 1e-9);  // points have 10 digits
}

TEST(PolyMeshGeometry, SnappyVolumeIsBoxMinusTube) {
  const PolyMesh& m = loaded("snappy_obstacle").mesh;
  const double r = 0.004, box = 0.02 * 0.02 * 0.06, tube = std::numbers::pi * r * r * 0.02;
  // The snapped tube is faceted by 0.5 mm cells: an inscribed polygon of about 50 sides
  // misses (2 pi / 50)^2 / 6 = 0.26 % of the hole (2.6 mm3); the box's moved vertical
  // edges (up to 20 um) change it by up to about 10 mm3. Together < 0.05 % of the volume.
  EXPECT_NEAR(m.total_volume(), box - tube, 5e-4 * (box - tube));
  EXPECT_GT(m.total_volume(), box - tube);  // faceting leaves more fluid, not less
  // The tube's faces: their area vectors sum to ~0 along its axis (y) and their area is
  // close to the mantle's (2 pi r L), slightly less for the faceted polygon.
  const auto& tube_patch = m.patches().at(3);
  double area = 0;
  for (std::int64_t f = tube_patch.start_face; f < tube_patch.start_face + tube_patch.n_faces; ++f)
    area += m.face_area(f).norm();
  EXPECT_NEAR(area, 2 * std::numbers::pi * r * 0.02, 0.01 * 2 * std::numbers::pi * r * 0.02);
}

TEST(PolyMeshGeometry, CellsAreClosedPositiveAndStarShapedFromTheirCentres) {
  for (const auto& name : kMeshes) {
    const PolyMesh& m = loaded(name).mesh;
    EXPECT_EQ(m.inverted_tet_count(), 0) << name;
    std::int64_t polyhedra = 0;
    for (std::int64_t c = 0; c < m.cell_count(); ++c) {
      ASSERT_GT(m.cell_volume(c), 0) << name << " cell " << c;
      Vector3d closed = Vector3d::Zero();
      for (const auto f : m.cell_faces(c)) closed += (m.owner(f) == c ? 1.0 : -1.0) * m.face_area(f);
      ASSERT_LE(closed.norm(), 1e-12 * std::cbrt(m.cell_volume(c)) * std::cbrt(m.cell_volume(c))) << name << " " << c;
      // Each cell's own centre is located in it (it is the apex of all its tetrahedra).
      ASSERT_TRUE(vfe::cell_contains(m, c, m.cell_centre(c))) << name << " " << c;
      polyhedra += m.cell_faces(c).size() != 6;
    }
    if (name == "snappy_obstacle") {
      EXPECT_GT(polyhedra, 1000);  // README: 1240 polyhedra (faces with 3-6 points)
    }
  }
}

TEST(PolyMeshGeometry, FaceAndCellFormulasOnKnownShapes) {
  // A unit cube and a tetrahedron built by hand.
  {
    const PolyMesh cube(block_mesh({nodes(1, 0, 1), nodes(1, 0, 1), nodes(1, 0, 1)}));
    EXPECT_DOUBLE_EQ(cube.cell_volume(0), 1.0);
    EXPECT_LE((cube.cell_centre(0) - Vector3d(0.5, 0.5, 0.5)).norm(), 1e-15);
    for (std::int64_t f = 0; f < cube.face_count(); ++f) EXPECT_DOUBLE_EQ(cube.face_area(f).norm(), 1.0);
  }
  {
    PolyMeshData d;
    d.points = {{0, 0, 0}, {2, 0, 0}, {0, 3, 0}, {0, 0, 4}};
    // Outward normals (owner 0, all boundary).
    d.face_points = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    d.face_offsets = {0, 3, 6, 9, 12};
    d.owner = {0, 0, 0, 0};
    const PolyMesh tet(d);
    EXPECT_NEAR(tet.cell_volume(0), 2.0 * 3.0 * 4.0 / 6.0, 1e-14);
    EXPECT_LE((tet.cell_centre(0) - Vector3d(0.5, 0.75, 1.0)).norm(), 1e-14);
    EXPECT_LE((tet.face_centre(0) - Vector3d(2.0 / 3, 1.0, 0)).norm(), 1e-15);
    EXPECT_LE((tet.face_area(0) - Vector3d(0, 0, -3)).norm(), 1e-15);
  }
  {
    // A warped quad (one corner lifted): area vector = half the cross product of the
    // diagonals; the centre is the area-weighted mean of the fan's triangle centroids.
    PolyMeshData d = block_mesh({nodes(1, 0, 1), nodes(1, 0, 1), nodes(1, 0, 1)});
    d.points[7].z() = 1.2;  // corner (1, 1, 1) up: the top face is warped
    const PolyMesh m(d);
    for (std::int64_t f = 0; f < m.face_count(); ++f) {
      const auto q = m.face(f);
      if (q.size() != 4) continue;
      const auto P = [&](int i) { return m.points()[std::size_t(q[std::size_t(i)])]; };
      const Vector3d expected = 0.5 * (P(2) - P(0)).cross(P(3) - P(1));
      EXPECT_LE((m.face_area(f) - expected).norm(), 1e-15) << f;
    }
    // OpenFOAM's volume of a cell with warped faces is close to, not equal to, the volume
    // enclosed by the faces' triangle fans (divergence theorem over the fans).
    double fan = 0;
    for (const auto f : m.cell_faces(0)) {
      const auto q = m.face(f);
      Vector3d mean = Vector3d::Zero();
      for (const auto i : q) mean += m.points()[std::size_t(i)];
      mean /= double(q.size());
      for (std::size_t i = 0; i < q.size(); ++i)
        fan += mean.dot(m.points()[std::size_t(q[i])].cross(m.points()[std::size_t(q[(i + 1) % q.size()])])) / 6.0;
    }
    EXPECT_GT(m.cell_volume(0), 1.0);
    EXPECT_NEAR(m.cell_volume(0), fan, 1e-3);
    EXPECT_TRUE(vfe::cell_contains(m, 0, m.cell_centre(0)));
    EXPECT_TRUE(vfe::cell_contains(m, 0, Vector3d(0.99, 0.99, 1.05)));  // under the lifted corner
    EXPECT_FALSE(vfe::cell_contains(m, 0, Vector3d(0.01, 0.01, 1.05)));
  }
}

// =======================================================================================
// Rectilinear grid

TEST(RectilinearGrid, ValidatesNodes) {
  expect_error([] { vfe::RectilinearGrid({std::vector<double>{0}, {0, 1}, {0, 1}}); }, VFE_ERROR_INVALID_ARGUMENT,
               {"axis x", "at least 2"});
  expect_error([] { vfe::RectilinearGrid({std::vector<double>{0, 1}, {0, 1, 1}, {0, 1}}); }, VFE_ERROR_INVALID_ARGUMENT,
               {"axis y", "node 2", "strictly increasing"});
  expect_error([] { vfe::RectilinearGrid({std::vector<double>{0, 1}, {0, 1}, {0, NAN}}); }, VFE_ERROR_INVALID_ARGUMENT,
               {"axis z", "finite"});
  // Cells whose volume underflows (or overflows) double.
  expect_error([] { vfe::RectilinearGrid({std::vector<double>{0, 1e-200}, {0, 1e-200}, {0, 1}}); }, VFE_ERROR_INVALID_ARGUMENT,
               {"cannot be computed in doubles"});
  expect_error([] { vfe::RectilinearGrid({std::vector<double>{-1e300, 1e300}, {0, 1e300}, {0, 1}}); },
               VFE_ERROR_INVALID_ARGUMENT, {"cannot be computed in doubles"});
}

TEST(RectilinearGrid, LocatesByBinarySearchWithCartesianTieRule) {
  const vfe::RectilinearGrid g({std::vector<double>{0, 1, 3, 7}, {-1, 0, 0.5}, {2, 2.25, 2.5, 3, 4}});
  EXPECT_EQ(g.cell_count(), 3 * 2 * 4);
  EXPECT_EQ(g.index(2, 1, 3), 2 + 3 * (1 + 2 * 3));
  EXPECT_EQ(g.locate({0.5, -0.5, 2.1}), 0);
  EXPECT_EQ(g.locate({1.0, -0.5, 2.1}), 1);  // interior node: the cell above
  EXPECT_EQ(g.locate({0.0, -1.0, 2.0}), 0);  // lower boundary: inside
  EXPECT_EQ(g.locate({7.0, -0.5, 2.1}), -1);  // upper boundary: outside
  EXPECT_EQ(g.locate({6.9, 0.49, 3.99}), g.index(2, 1, 3));
  EXPECT_EQ(g.locate({-0.1, 0, 2.1}), -1);
  EXPECT_EQ(g.locate({NAN, 0, 2.1}), -1);
  EXPECT_EQ(g.nearest({-5, 9, 3.1}), g.index(0, 1, 3));
  double total = 0;
  for (const double v : g.cell_volumes()) total += v;
  EXPECT_DOUBLE_EQ(total, 7 * 1.5 * 2);
  EXPECT_DOUBLE_EQ(g.cell_volume(g.index(2, 0, 3)), 4 * 1 * 1);
  EXPECT_EQ(g.cell_centre(g.index(1, 1, 2)), Vector3d(2, 0.25, 2.75));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.5, 8);
  for (int n = 0; n < 2000; ++n) {
    const Vector3d p(u(rng), u(rng) / 4, 2 + u(rng) / 4);
    std::int64_t brute = -1;
    for (std::int64_t c = 0; c < g.cell_count(); ++c) {
      const auto [i, j, k] = g.ijk(c);
      const bool in = g.nodes(0)[std::size_t(i)] <= p.x() && p.x() < g.nodes(0)[std::size_t(i) + 1] &&
                      g.nodes(1)[std::size_t(j)] <= p.y() && p.y() < g.nodes(1)[std::size_t(j) + 1] &&
                      g.nodes(2)[std::size_t(k)] <= p.z() && p.z() < g.nodes(2)[std::size_t(k) + 1];
      if (in) brute = c;
    }
    ASSERT_EQ(g.locate(p), brute) << p.transpose();
  }
}

// =======================================================================================
// Exact predicates

TEST(Predicates, Orient3dIsExactAndTieBreaksConsistently) {
  // Integer coordinates up to 2^24 around a large offset: the exact determinant fits
  // __int128, and coplanar points defeat the floating-point filter.
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<std::int64_t> u(-(1 << 24), 1 << 24);
  std::uniform_int_distribution<int> small(-3, 3);
  const auto det = [](const std::array<std::int64_t, 3>& a, const std::array<std::int64_t, 3>& b,
                      const std::array<std::int64_t, 3>& c, const std::array<std::int64_t, 3>& d) {
    __int128 m[3][3];
    for (int i = 0; i < 3; ++i) {
      m[0][i] = b[std::size_t(i)] - a[std::size_t(i)];
      m[1][i] = c[std::size_t(i)] - a[std::size_t(i)];
      m[2][i] = d[std::size_t(i)] - a[std::size_t(i)];
    }
    const __int128 v = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    return (v > 0) - (v < 0);
  };
  const auto vec = [](const std::array<std::int64_t, 3>& a) { return Vector3d(double(a[0]), double(a[1]), double(a[2])); };
  int zeros = 0;
  for (int n = 0; n < 20000; ++n) {
    std::array<std::int64_t, 3> a, e1, e2, b, c, d;
    for (int i = 0; i < 3; ++i) {
      a[std::size_t(i)] = u(rng);
      e1[std::size_t(i)] = small(rng);
      e2[std::size_t(i)] = small(rng);
    }
    for (int i = 0; i < 3; ++i) {
      b[std::size_t(i)] = a[std::size_t(i)] + 1000 * e1[std::size_t(i)];
      c[std::size_t(i)] = a[std::size_t(i)] + 1000 * e2[std::size_t(i)];
      // d in the plane (often), or off it by one unit
      d[std::size_t(i)] = a[std::size_t(i)] + 7 * e1[std::size_t(i)] - 5 * e2[std::size_t(i)] + (n % 3 == 0 ? small(rng) : 0);
    }
    const int expected = det(a, b, c, d);
    zeros += expected == 0;
    ASSERT_EQ(vfe::geom::orient3d_exact(vec(a), vec(b), vec(c), vec(d)), expected) << n;
    const int s = vfe::geom::orient3d_sos(vec(a), vec(b), vec(c), vec(d));
    if (expected != 0) {
      ASSERT_EQ(s, expected);
    }
    // Odd permutations flip the sign, even ones keep it, ties included.
    ASSERT_EQ(vfe::geom::orient3d_sos(vec(b), vec(a), vec(c), vec(d)), -s);
    ASSERT_EQ(vfe::geom::orient3d_sos(vec(b), vec(c), vec(a), vec(d)), s);
  }
  EXPECT_GT(zeros, 5000);
  // The tie rule: a point in the plane z = 0 goes to the +z side when the plane's normal
  // has no x or y component, and to the +x side when it has one.
  const Vector3d o(0, 0, 0), x(1, 0, 0), y(0, 1, 0), p(0.3, 0.2, 0);
  EXPECT_EQ(vfe::geom::orient3d_sos(o, x, y, p), 1);   // normal +z
  EXPECT_EQ(vfe::geom::orient3d_sos(o, y, x, p), -1);  // normal -z
  const Vector3d z(0, 0, 1), q(0, 0.2, 0.3);
  EXPECT_EQ(vfe::geom::orient3d_sos(o, y, z, q), 1);  // normal +x
}

// =======================================================================================
// Point location

namespace {

struct LocateStats {
  std::int64_t inside = 0, outside = 0;
};

/// Checks every locator against brute force at p; returns the brute-force cell.
std::int64_t check_point(const std::string& name, const Loaded& l, const Vector3d& p, std::int64_t walk_start,
                         LocateStats& stats) {
  const auto claims = claiming_cells(l.mesh, p);
  EXPECT_LE(claims.size(), 1u) << name << " point " << p.transpose() << " claimed by " << claims.size() << " cells";
  const std::int64_t brute = claims.empty() ? -1 : claims.front();
  EXPECT_EQ(vfe::locate_brute_force(l.mesh, p), brute);
  EXPECT_EQ(l.locator->hash().locate(p), brute) << name << " hash at " << p.transpose();
  EXPECT_EQ(l.locator->kdtree().locate(p), brute) << name << " kd-tree at " << p.transpose();
  EXPECT_EQ(l.locator->walk().locate(p, walk_start), brute) << name << " walk from " << walk_start << " at " << p.transpose();
  (brute >= 0 ? stats.inside : stats.outside)++;
  return brute;
}

/// Coordinates shared by the mesh points along axis d (the grid planes of a block mesh).
std::vector<double> planes(const PolyMesh& m, int d) {
  std::set<double> s;
  for (const auto& p : m.points()) s.insert(p[d]);
  return {s.begin(), s.end()};
}

}  // namespace

class PolyMeshLocate : public ::testing::TestWithParam<std::string> {};

TEST_P(PolyMeshLocate, RandomPointsAgreeWithBruteForce) {
  const std::string name = GetParam();
  const Loaded& l = loaded(name);
  const PolyMesh& m = l.mesh;
  std::mt19937_64 rng(2024);
  const Vector3d lo = m.bounds().min(), hi = m.bounds().max(), ext = hi - lo;
  std::uniform_real_distribution<double> u(-0.05, 1.05);
  std::uniform_int_distribution<std::int64_t> cell(0, m.cell_count() - 1);
  LocateStats stats;
  for (int n = 0; n < 2000; ++n) {
    const Vector3d p = lo + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(ext);
    const std::int64_t c = check_point(name, l, p, cell(rng), stats);
    if (name.rfind("box", 0) == 0 && (p.array() > lo.array()).all() && (p.array() < hi.array()).all()) {
      ASSERT_GE(c, 0) << "a point inside the box is in no cell: " << p.transpose();
    }
    if (name == "cylinder_ogrid_coarse") {
      const double r = std::hypot(p.x() - 0.01, p.y() - 0.01);
      if (r < 0.0098 && p.z() > 0 && p.z() < 0.06) {
        ASSERT_GE(c, 0) << p.transpose();
      }
      if (r > 0.0100001) {
        ASSERT_EQ(c, -1) << p.transpose();
      }
    }
    if (name == "snappy_obstacle") {
      const double r = std::hypot(p.x() - 0.01, p.z() - 0.03);
      if (r < 0.0039) {
        ASSERT_EQ(c, -1) << "a point in the tube is in cell " << c;
      }
      const bool well_inside = (p - lo).minCoeff() > 1e-4 && (hi - p).minCoeff() > 1e-4;
      if (r > 0.0042 && well_inside) {
        ASSERT_GE(c, 0) << p.transpose();
      }
    }
  }
  EXPECT_GT(stats.inside, 1000);
  EXPECT_GT(stats.outside, 100);
}

TEST_P(PolyMeshLocate, PointsOnVerticesFacesEdgesAndCentresBelongToExactlyOneCell) {
  const std::string name = GetParam();
  const Loaded& l = loaded(name);
  const PolyMesh& m = l.mesh;
  std::mt19937_64 rng(99);
  std::uniform_int_distribution<std::int64_t> cell(0, m.cell_count() - 1), face(0, m.face_count() - 1),
      internal(0, m.internal_face_count() - 1), point(0, m.point_count() - 1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<bool> on_boundary(std::size_t(m.point_count()), false);
  for (std::int64_t f = m.internal_face_count(); f < m.face_count(); ++f)
    for (const auto q : m.face(f)) on_boundary[std::size_t(q)] = true;
  LocateStats stats;
  const auto expect_one = [&](const Vector3d& p, const char* what) {
    const auto claims = claiming_cells(m, p);
    EXPECT_EQ(claims.size(), 1u) << name << " " << what << " " << p.transpose();
  };
  for (int n = 0; n < 300; ++n) {
    // Cell centre: the apex of all the cell's tetrahedra, and in that cell.
    const std::int64_t c = cell(rng);
    EXPECT_EQ(check_point(name, l, m.cell_centre(c), cell(rng), stats), c);
    // Apex of an internal face (a vertex of the tetrahedra of both cells) and points on
    // its fan triangles and spokes.
    const std::int64_t f = internal(rng);
    const Vector3d& apex = m.face_apex(f);
    const auto q = m.face(f);
    const Vector3d& a = m.points()[std::size_t(q[0])];
    const Vector3d& b = m.points()[std::size_t(q[1])];
    const double s = u(rng), t = u(rng) * (1 - s);
    for (const Vector3d& p : {apex, Vector3d(apex + s * (a - apex) + t * (b - apex)), Vector3d(0.5 * (apex + a)),
                              Vector3d(0.5 * (a + b))}) {
      const std::int64_t got = check_point(name, l, p, m.owner(f), stats);
      if (p == apex) {
        EXPECT_TRUE(got == m.owner(f) || got == m.neighbour(f)) << name;
      }
      const bool boundary_edge = p == 0.5 * (a + b) && on_boundary[std::size_t(q[0])] && on_boundary[std::size_t(q[1])];
      if (!boundary_edge) expect_one(p, "point on an internal face");
    }
    // Mesh vertices (interior ones: exactly one cell; boundary ones: at most one).
    const std::int64_t v = point(rng);
    check_point(name, l, m.points()[std::size_t(v)], cell(rng), stats);
    if (!on_boundary[std::size_t(v)]) expect_one(m.points()[std::size_t(v)], "interior vertex");
    // Any face, boundary ones included: its apex.
    check_point(name, l, m.face_apex(face(rng)), cell(rng), stats);
  }
  EXPECT_GT(stats.inside, 1500);
}

TEST_P(PolyMeshLocate, WalkFollowsClusteredPointsAndFallsBackCorrectly) {
  const std::string name = GetParam();
  const Loaded& l = loaded(name);
  const PolyMesh& m = l.mesh;
  const auto& walk = l.locator->walk();
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<std::int64_t> cell(0, m.cell_count() - 1);
  std::normal_distribution<double> g(0, 1);
  const double h = std::cbrt(m.total_volume() / double(m.cell_count()));
  std::int64_t found = 0, fallbacks = 0, points = 0;
  for (int n = 0; n < 200; ++n) {
    // Sub-elements of a particle of diameter ~ one cell around a cell centre, each located
    // from the previous one's cell (the engine's pattern).
    const Vector3d centre = m.cell_centre(cell(rng));
    std::int64_t prev = l.locator->locate(centre);
    ASSERT_GE(prev, 0);
    for (int k = 0; k < 20; ++k) {
      const Vector3d p = centre + 0.4 * h * Vector3d(g(rng), g(rng), g(rng));
      const auto r = walk.walk(p, prev);
      const std::int64_t expected = vfe::locate_brute_force(m, p);
      if (r.stop == vfe::NeighbourWalk::Stop::kInside) {
        ASSERT_EQ(r.cell, expected);
        ++found;
      } else {
        ++fallbacks;
      }
      const std::int64_t got = l.locator->locate_from(p, prev);
      ASSERT_EQ(got, expected);
      if (got >= 0) prev = got;
      ++points;
    }
  }
  // The walk alone settles nearly all of them; the rest leave the mesh (fallback says -1
  // or finds them behind a boundary).
  EXPECT_GT(found, points * 8 / 10) << name;
  // From far away (cell 0 to anywhere), including across the snappy mesh's tube.
  std::uniform_real_distribution<double> u(0, 1);
  for (int n = 0; n < 200; ++n) {
    const Vector3d p = m.bounds().min() + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(m.bounds().sizes());
    ASSERT_EQ(l.locator->locate_from(p, 0), vfe::locate_brute_force(m, p));
    ASSERT_EQ(l.locator->locate_from(p, -5), vfe::locate_brute_force(m, p));
  }
}

TEST_P(PolyMeshLocate, NearestCellIsTheNearestCentre) {
  const Loaded& l = loaded(GetParam());
  const PolyMesh& m = l.mesh;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-0.5, 1.5);
  for (int n = 0; n < 200; ++n) {
    const Vector3d p = m.bounds().min() + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(m.bounds().sizes());
    double best = INFINITY;
    for (const auto& c : m.cell_centres()) best = std::min(best, (c - p).squaredNorm());
    const std::int64_t got = l.locator->nearest_cell(p);
    ASSERT_GE(got, 0);
    ASSERT_NEAR((m.cell_centre(got) - p).squaredNorm(), best, 1e-12 * best);
  }
}

TEST_P(PolyMeshLocate, OutsideAndNonFinitePointsGiveMinusOne) {
  const Loaded& l = loaded(GetParam());
  const PolyMesh& m = l.mesh;
  const Vector3d hi = m.bounds().max(), lo = m.bounds().min();
  for (const Vector3d& p : {Vector3d(hi + Vector3d(1e-9, 0, 0)), Vector3d(lo - Vector3d(0, 0, 1e-9)), Vector3d(1e3, 1e3, 1e3),
                            Vector3d(NAN, 0.01, 0.01), Vector3d(0.01, INFINITY, 0.01)}) {
    EXPECT_EQ(l.locator->locate(p), -1) << p.transpose();
    EXPECT_EQ(l.locator->kdtree().locate(p), -1) << p.transpose();
    EXPECT_EQ(l.locator->locate_from(p, 3), -1) << p.transpose();
  }
}

TEST_P(PolyMeshLocate, ConcurrentQueriesGiveTheSameAnswers) {
  const Loaded& l = loaded(GetParam());
  const PolyMesh& m = l.mesh;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vector3d> pts(4000);
  for (auto& p : pts) p = m.bounds().min() + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(m.bounds().sizes());
  std::vector<std::int64_t> serial(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) serial[i] = l.locator->locate(pts[i]);
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (std::size_t i = std::size_t(t); i < pts.size(); i += 2) {
        const auto& p = pts[i];
        if (l.locator->kdtree().locate(p) != serial[i]) ++mismatches;
        if (l.locator->locate_from(p, serial[(i + 1) % pts.size()] < 0 ? 0 : serial[(i + 1) % pts.size()]) != serial[i]) ++mismatches;
        if (l.locator->locate(p) != serial[i]) ++mismatches;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0);
}

TEST_P(PolyMeshLocate, FastPathsMatchThePlainTetrahedronTest) {
  // cell_contains decides most points from plane distances, convex cells from their face
  // planes; the definition is the tetrahedra (centre, apex, a, b) with the displaced-point
  // signs. Compare on points near and on the cells.
  const PolyMesh& m = loaded(GetParam()).mesh;
  const auto in_tets = [&](std::int64_t c, const Vector3d& p) {
    using vfe::geom::orient3d_sos;
    for (const auto f : m.cell_faces(c)) {
      const auto q = m.face(f);
      for (std::size_t i = 0; i < q.size(); ++i) {
        Vector3d v[4] = {m.face_apex(f), m.points()[std::size_t(q[i])], m.points()[std::size_t(q[(i + 1) % q.size()])],
                         m.cell_centre(c)};
        if (m.owner(f) == c) std::swap(v[1], v[2]);  // positive orientation
        // p inside iff replacing any vertex by p keeps the orientation positive.
        bool inside = true;
        for (int k = 0; k < 4 && inside; ++k) {
          Vector3d w[4] = {v[0], v[1], v[2], v[3]};
          w[k] = p;
          // orient(w0, w1, w2, w3) with p moved to the last place (sign of the permutation).
          static const int perm[4][4] = {{1, 2, 3, 0}, {0, 2, 3, 1}, {0, 1, 3, 2}, {0, 1, 2, 3}};
          static const int sign[4] = {-1, 1, -1, 1};
          inside = sign[k] * orient3d_sos(w[perm[k][0]], w[perm[k][1]], w[perm[k][2]], w[perm[k][3]]) > 0;
        }
        if (inside) return true;
      }
    }
    return false;
  };
  std::mt19937_64 rng(31);
  std::uniform_int_distribution<std::int64_t> cell(0, m.cell_count() - 1);
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  std::int64_t inside = 0, checked = 0;
  for (int n = 0; n < 3000; ++n) {
    const std::int64_t c = cell(rng);
    const auto& b = m.cell_bounds(c);
    std::vector<Vector3d> pts = {b.min() + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(b.sizes()), m.cell_centre(c)};
    for (const auto f : m.cell_faces(c)) {
      pts.push_back(m.face_apex(f));
      pts.push_back(m.points()[std::size_t(m.face(f)[0])]);
    }
    for (const auto& p : pts) {
      const bool expected = in_tets(c, p);
      ASSERT_EQ(vfe::cell_contains(m, c, p), expected) << GetParam() << " cell " << c << " at " << p.transpose();
      inside += expected;
      ++checked;
    }
  }
  EXPECT_GT(inside, checked / 20);
}

INSTANTIATE_TEST_SUITE_P(Meshes, PolyMeshLocate, ::testing::ValuesIn(kMeshes),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

TEST(PolyMeshLocateTieRule, BoxUniformFollowsTheCartesianRuleOnFacesEdgesAndVertices) {
  // On the blockMesh box, points on grid planes go to the cell above, lower boundary
  // points are inside and upper boundary points outside: the RectilinearGrid's answer.
  const Loaded& l = loaded("box_uniform_10x10x30");
  const PolyMesh& m = l.mesh;
  const std::array<std::vector<double>, 3> x = {planes(m, 0), planes(m, 1), planes(m, 2)};
  ASSERT_EQ(x[0].size(), 11u);
  ASSERT_EQ(x[2].size(), 31u);
  const vfe::RectilinearGrid grid(x);
  std::mt19937_64 rng(8);
  std::uniform_int_distribution<int> pick(0, 3);
  std::uniform_real_distribution<double> u(-0.01, 1.01);
  for (int n = 0; n < 3000; ++n) {
    Vector3d p;
    for (int d = 0; d < 3; ++d) {
      const auto& xd = x[std::size_t(d)];
      // On a grid plane (boundaries included) or anywhere.
      p[d] = pick(rng) ? xd[std::size_t(std::uniform_int_distribution<std::size_t>(0, xd.size() - 1)(rng))]
                       : xd.front() + u(rng) * (xd.back() - xd.front());
    }
    const std::int64_t expected = grid.locate(p);
    ASSERT_EQ(l.locator->locate(p), expected) << p.transpose();
    ASSERT_EQ(l.locator->kdtree().locate(p), expected) << p.transpose();
    ASSERT_EQ(l.locator->locate_from(p, 0), expected) << p.transpose();
    ASSERT_EQ(claiming_cells(m, p).size(), expected >= 0 ? 1u : 0u) << p.transpose();
  }
}

TEST(PolyMeshLocateTieRule, GradedBlockInMemoryMatchesRectilinearGrid) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> step(0.1, 1.0);
  std::array<std::vector<double>, 3> x;
  for (int d = 0; d < 3; ++d) {
    x[std::size_t(d)] = {-0.3 * d};
    for (int i = 0; i < 4 + 2 * d; ++i) x[std::size_t(d)].push_back(x[std::size_t(d)].back() + step(rng));
  }
  const PolyMesh m(block_mesh(x));
  const CellLocator loc(m);
  const vfe::RectilinearGrid grid(x);
  ASSERT_EQ(m.cell_count(), grid.cell_count());
  for (std::int64_t c = 0; c < m.cell_count(); ++c) {
    ASSERT_NEAR(m.cell_volume(c), grid.cell_volume(c), 1e-14);
    ASSERT_LE((m.cell_centre(c) - grid.cell_centre(c)).norm(), 1e-14);
  }
  std::uniform_int_distribution<int> pick(0, 2);
  std::uniform_real_distribution<double> u(-0.05, 1.05);
  for (int n = 0; n < 5000; ++n) {
    Vector3d p;
    for (int d = 0; d < 3; ++d) {
      const auto& xd = x[std::size_t(d)];
      p[d] = pick(rng) ? xd[std::size_t(std::uniform_int_distribution<std::size_t>(0, xd.size() - 1)(rng))]
                       : xd.front() + u(rng) * (xd.back() - xd.front());
    }
    const std::int64_t expected = grid.locate(p);
    ASSERT_EQ(vfe::locate_brute_force(m, p), expected) << p.transpose();
    ASSERT_EQ(claiming_cells(m, p).size(), expected >= 0 ? 1u : 0u) << p.transpose();
    ASSERT_EQ(loc.locate(p), expected);
    ASSERT_EQ(loc.kdtree().locate(p), expected);
    ASSERT_EQ(loc.locate_from(p, std::int64_t(n) % m.cell_count()), expected);
  }
}

TEST(PolyMeshLocateTieRule, ParametersAreValidated) {
  const PolyMesh m(block_mesh({nodes(2, 0, 1), nodes(2, 0, 1), nodes(2, 0, 1)}));
  const vfe::SpatialHash hash(m);
  expect_error([&] { vfe::SpatialHash(m, 0.0); }, VFE_ERROR_INVALID_ARGUMENT, {"bins_per_cell"});
  expect_error([&] { vfe::KdTreeLocator(m, hash, 0); }, VFE_ERROR_INVALID_ARGUMENT, {"k is 0"});
  for (const double bins : {0.01, 1.0, 50.0}) {
    const vfe::SpatialHash h(m, bins);
    EXPECT_EQ(h.locate({0.3, 0.6, 0.9}), 0 + 2 * (1 + 2 * 1));
  }
}

// Labels and counts near 2^63 once overflowed label + 1 and the topology check wrote out
// of bounds; every format must refuse them with the file, the entry and the limit.
TEST(PolyMeshReader, LabelsAndCountsNear2To63AreRefusedInEveryFormat) {
  PolyMeshData bad = block_mesh({nodes(2, 0, 2), nodes(1, 0, 1), nodes(1, 0, 1)});
  const std::int64_t huge = std::numeric_limits<std::int64_t>::max() - 1;
  for (const char* list : {"owner", "neighbour"}) {
    PolyMeshData d = bad;
    (std::string(list) == "owner" ? d.owner.back() : d.neighbour.front()) = huge;
    for (int format = 0; format < 3; ++format) {
      SCOPED_TRACE(std::string(list) + " format " + std::to_string(format));
      TempDir t;
      if (format == 2) {
        write_binary<std::int64_t>(t.path, d);
      } else {
        write_ascii(t.path, d);
        if (format == 1) {  // gzip the list holding the label
          const std::string text = read_text(t.path / list);
          fs::remove(t.path / list);
          write_gzip(t.path / (std::string(list) + ".gz"), text);
        }
      }
      expect_error([&] { vfe::read_polymesh(t.path); }, VFE_ERROR_INVALID_ARGUMENT,
                   {list, std::to_string(huge), "fewer than " + std::to_string(d.owner.size()) + " cells"});
      vfe_engine* e = nullptr;
      EXPECT_EQ(vfe_create_polymesh(t.path.string().c_str(), &e), VFE_ERROR_INVALID_ARGUMENT);
      EXPECT_EQ(e, nullptr);
    }
  }
  // The same labels given directly to PolyMesh (not through the reader).
  PolyMeshData direct = bad;
  direct.owner.back() = huge;
  expect_error([&] { PolyMesh m(direct); }, VFE_ERROR_INVALID_ARGUMENT, {"owner of face", std::to_string(huge)});
  // nFaces (and startFace) of a patch near 2^63.
  TempDir t;
  write_ascii(t.path, bad);
  std::string b = read_text(t.path / "boundary");
  const auto at = b.find("nFaces          ");
  ASSERT_NE(at, std::string::npos);
  b.replace(at + 16, b.find(';', at) - at - 16, std::to_string(std::numeric_limits<std::int64_t>::max()));
  write_text(t.path / "boundary", b);
  expect_error([&] { vfe::read_polymesh(t.path); }, VFE_ERROR_INVALID_ARGUMENT,
               {"boundary", "nFaces 9223372036854775807", "has only"});
  // A uniform point list that asks for gigabytes from a few bytes.
  write_text(t.path / "points", foam_header("vectorField", "points") + "67108864{(0 0 0)}\n");
  expect_error([&] { vfe::read_polymesh(t.path); }, VFE_ERROR_INVALID_ARGUMENT, {"points", "67108864", "65536"});
}

// A faceCompactList whose offsets decrease (their differences could overflow).
TEST(PolyMeshReader, DecreasingCompactFaceOffsetsAreRefused) {
  PolyMeshData d = block_mesh({nodes(1, 0, 1), nodes(1, 0, 1), nodes(1, 0, 1)});
  d.face_offsets[2] = std::numeric_limits<std::int64_t>::min() + 5;
  TempDir t;
  write_binary<std::int64_t>(t.path, d);
  expect_error([&] { vfe::read_polymesh(t.path); }, VFE_ERROR_INVALID_ARGUMENT, {"faces", "face offset 2", "decrease"});
}

// A folder where a polyMesh file should be is an I/O error with a message, not an
// internal one.
TEST(PolyMeshReader, FolderInPlaceOfAFileIsAnIoError) {
  TempDir t;
  write_ascii(t.path, block_mesh({nodes(1, 0, 1), nodes(1, 0, 1), nodes(1, 0, 1)}));
  fs::remove(t.path / "owner");
  fs::create_directories(t.path / "owner");
  expect_error([&] { vfe::read_polymesh(t.path); }, VFE_ERROR_IO, {"owner", "not a regular file"});
  vfe_engine* e = nullptr;
  EXPECT_EQ(vfe_create_polymesh(t.path.string().c_str(), &e), VFE_ERROR_IO);
  EXPECT_EQ(e, nullptr);
}

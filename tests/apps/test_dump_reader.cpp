// LIGGGHTS/LAMMPS dump reader: columns by name, gzip, empty frames, and errors that name
// the file, the line and the problem.
#include "dump_reader.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

using namespace vfe::apps;
using vfe::apps::test::TempDir;
using vfe::apps::test::write_gzip;
using vfe::apps::test::write_text;

namespace {

// Three atoms, LIGGGHTS style (every line ends with a space).
const std::string kFrame =
    "ITEM: TIMESTEP\n"
    "30000\n"
    "ITEM: NUMBER OF ATOMS\n"
    "3\n"
    "ITEM: BOX BOUNDS ff ff ff\n"
    "0 0.02\n"
    "0 0.02\n"
    "0 0.06\n"
    "ITEM: ATOMS id type x y z radius vx vy vz omegax omegay omegaz \n"
    "1 1 0.0169042 0.0161652 0.000493098 0.0005 1.18401e-07 2.87869e-07 -8.22884e-07 -0.0009 -0.0004 0.0007 \n"
    "2 2 0.00748598 0.000496899 0.00121141 0.0003 1.86359e-06 -1.99516e-07 -8.60847e-07 0.1 0.2 0.3 \n"
    "7 1 0.0137333 0.00458359 0.00294174 0.0005 6.50034e-07 -2.7898e-06 -5.63161e-06 0 0 0 \n";

void expect_three_atoms(const DumpFrame& f) {
  EXPECT_EQ(f.timestep, 30000);
  ASSERT_EQ(f.n, 3);
  ASSERT_EQ(f.centres.size(), 9u);
  ASSERT_EQ(f.radii.size(), 3u);
  EXPECT_DOUBLE_EQ(f.centres[0], 0.0169042);
  EXPECT_DOUBLE_EQ(f.centres[4], 0.000496899);
  EXPECT_DOUBLE_EQ(f.centres[8], 0.00294174);
  EXPECT_DOUBLE_EQ(f.radii[1], 0.0003);
  ASSERT_EQ(f.ids.size(), 3u);
  EXPECT_EQ(f.ids[2], 7);
  ASSERT_EQ(f.types.size(), 3u);
  EXPECT_EQ(f.types[1], 2);
  ASSERT_EQ(f.velocities.size(), 9u);
  EXPECT_DOUBLE_EQ(f.velocities[3], 1.86359e-06);
  EXPECT_TRUE(f.orientations.empty());
  EXPECT_EQ(f.box[1], 0.02);
  EXPECT_EQ(f.box[5], 0.06);
  EXPECT_EQ(f.box_flags, "ff ff ff");
  const double v = 4.0 / 3.0 * std::numbers::pi * (2 * std::pow(0.0005, 3) + std::pow(0.0003, 3));
  EXPECT_NEAR(f.total_volume(), v, 1e-18);
  const auto view = f.view();
  EXPECT_EQ(view.n, 3);
  EXPECT_EQ(view.centres, f.centres.data());
  EXPECT_EQ(view.orientations, nullptr);
}

/// Message of the DumpError that reading path throws ("" if none).
std::string error_of(const std::filesystem::path& path) {
  try {
    (void)read_dump_frame(path.string());
  } catch (const DumpError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(DumpReader, ReadsPlainText) {
  TempDir dir;
  write_text(dir / "a.dump", kFrame);
  expect_three_atoms(read_dump_frame((dir / "a.dump").string()));
}

TEST(DumpReader, ReadsGzip) {
  TempDir dir;
  write_gzip(dir / "a.dump.gz", kFrame);
  expect_three_atoms(read_dump_frame((dir / "a.dump.gz").string()));
}

TEST(DumpReader, ReadsGzipWithoutGzSuffix) {
  TempDir dir;
  write_gzip(dir / "compressed.dump", kFrame);
  expect_three_atoms(read_dump_frame((dir / "compressed.dump").string()));
}

TEST(DumpReader, LastLineWithoutNewlineAndCrlf) {
  TempDir dir;
  std::string text = kFrame;
  for (std::size_t p = 0; (p = text.find('\n', p)) != std::string::npos; p += 2) text.replace(p, 1, "\r\n");
  text.resize(text.size() - 2);  // no line end at the end of the file
  write_text(dir / "a.dump", text);
  expect_three_atoms(read_dump_frame((dir / "a.dump").string()));
}

TEST(DumpReader, MapsColumnsByName) {
  TempDir dir;
  write_text(dir / "a.dump",
             "ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp ff\n-1 1\n-2 2\n0 4\n"
             "ITEM: ATOMS radius z type y id x \n"
             "0.25 3.5 4 -1.5 10 0.5 \n"
             "0.125 0.5 1 1.5 11 -0.5 \n");
  const DumpFrame f = read_dump_frame((dir / "a.dump").string());
  ASSERT_EQ(f.n, 2);
  EXPECT_EQ(f.centres, (std::vector<double>{0.5, -1.5, 3.5, -0.5, 1.5, 0.5}));
  EXPECT_EQ(f.radii, (std::vector<double>{0.25, 0.125}));
  EXPECT_EQ(f.ids, (std::vector<std::int64_t>{10, 11}));
  EXPECT_EQ(f.types, (std::vector<std::int32_t>{4, 1}));
  EXPECT_TRUE(f.velocities.empty());
  EXPECT_EQ(f.box_flags, "pp pp ff");
  EXPECT_EQ(f.columns.size(), 6u);
}

TEST(DumpReader, DiameterColumnGivesRadius) {
  TempDir dir;
  write_text(dir / "a.dump",
             "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\n"
             "ITEM: ATOMS x y z diameter \n0.5 0.5 0.5 0.002 \n");
  const DumpFrame f = read_dump_frame((dir / "a.dump").string());
  ASSERT_EQ(f.radii.size(), 1u);
  EXPECT_DOUBLE_EQ(f.radii[0], 0.001);
  EXPECT_TRUE(f.ids.empty());
  EXPECT_TRUE(f.types.empty());
}

TEST(DumpReader, ScaledCoordinatesUseTheBox) {
  TempDir dir;
  write_text(dir / "a.dump",
             "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS ff ff ff\n1 3\n-1 1\n0 10\n"
             "ITEM: ATOMS id xs ys zs radius \n1 0.5 0.25 0.1 0.01 \n");
  const DumpFrame f = read_dump_frame((dir / "a.dump").string());
  ASSERT_EQ(f.centres.size(), 3u);
  EXPECT_DOUBLE_EQ(f.centres[0], 2.0);
  EXPECT_DOUBLE_EQ(f.centres[1], -0.5);
  EXPECT_DOUBLE_EQ(f.centres[2], 1.0);
}

TEST(DumpReader, ReadsQuaternions) {
  TempDir dir;
  write_text(dir / "a.dump",
             "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\n"
             "ITEM: ATOMS id x y z radius quatw quati quatj quatk \n1 0.5 0.5 0.5 0.1 0.5 0.5 -0.5 0.5 \n");
  DumpFrame f = read_dump_frame((dir / "a.dump").string());
  EXPECT_EQ(f.orientations, (std::vector<double>{0.5, 0.5, -0.5, 0.5}));
  EXPECT_EQ(f.view().orientations, f.orientations.data());

  write_text(dir / "b.dump",
             "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\n"
             "ITEM: ATOMS q4 q3 q2 q1 x y z radius \n0.4 0.3 0.2 0.1 0.5 0.5 0.5 0.1 \n");
  f = read_dump_frame((dir / "b.dump").string());
  EXPECT_EQ(f.orientations, (std::vector<double>{0.1, 0.2, 0.3, 0.4}));
}

TEST(DumpReader, EmptyFrameAndFrameSelection) {
  TempDir dir;
  const std::string empty =
      "ITEM: TIMESTEP\n100\nITEM: NUMBER OF ATOMS\n0\nITEM: BOX BOUNDS ff ff ff\n0 0.02\n0 0.02\n0 0.06\n"
      "ITEM: ATOMS id type x y z radius \n";
  std::string later = kFrame;
  later.replace(later.find("30000"), 5, "30100");
  write_gzip(dir / "frames.dump.gz", empty + kFrame + later);

  const auto frames = read_dump((dir / "frames.dump.gz").string());
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].n, 0);
  EXPECT_EQ(frames[0].timestep, 100);
  EXPECT_TRUE(frames[0].centres.empty());
  EXPECT_EQ(frames[0].view().n, 0);
  EXPECT_EQ(frames[0].total_volume(), 0.0);
  EXPECT_EQ(frames[2].timestep, 30100);

  EXPECT_EQ(read_dump_frame((dir / "frames.dump.gz").string()).timestep, 30100);  // last by default
  EXPECT_EQ(read_dump_frame((dir / "frames.dump.gz").string(), {0}).n, 0);
  EXPECT_EQ(read_dump_frame((dir / "frames.dump.gz").string(), {-2}).timestep, 30000);
  EXPECT_THROW(read_dump_frame((dir / "frames.dump.gz").string(), {3}), DumpError);

  DumpReader reader((dir / "frames.dump.gz").string());
  EXPECT_TRUE(reader.skip());
  DumpFrame f;
  EXPECT_TRUE(reader.next(f));
  expect_three_atoms(f);
  EXPECT_TRUE(reader.next(f));
  EXPECT_FALSE(reader.next(f));
}

TEST(DumpReaderErrors, MissingRadiusColumn) {
  TempDir dir;
  std::string text = kFrame;
  text.replace(text.find(" radius "), 8, " mass ");
  write_text(dir / "noradius.dump", text);
  const std::string msg = error_of(dir / "noradius.dump");
  EXPECT_NE(msg.find("noradius.dump:9:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no radius column"), std::string::npos) << msg;
  EXPECT_NE(msg.find("diameter"), std::string::npos) << msg;  // how to fix it
}

TEST(DumpReaderErrors, MissingPositionColumn) {
  TempDir dir;
  std::string text = kFrame;
  text.replace(text.find(" z radius"), 9, " zz radius");
  write_text(dir / "a.dump", text);
  const std::string msg = error_of(dir / "a.dump");
  EXPECT_NE(msg.find("no position columns"), std::string::npos) << msg;
}

TEST(DumpReaderErrors, TruncatedAtomLines) {
  TempDir dir;
  std::string text = kFrame;
  text.resize(text.rfind("7 1 "));  // the third atom line is missing
  write_text(dir / "cut.dump", text);
  const std::string msg = error_of(dir / "cut.dump");
  EXPECT_NE(msg.find("cut.dump:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("2 of 3 atom lines"), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;

  // The same when the next frame starts too early.
  write_text(dir / "early.dump", text + kFrame);
  const std::string msg2 = error_of(dir / "early.dump");
  EXPECT_NE(msg2.find("early.dump:12:"), std::string::npos) << msg2;
  EXPECT_NE(msg2.find("2 of 3 atom lines"), std::string::npos) << msg2;
}

TEST(DumpReaderErrors, WrongNumberOfValues) {
  TempDir dir;
  std::string text = kFrame;
  const std::string tail = "1.86359e-06 -1.99516e-07 -8.60847e-07 0.1 0.2 0.3 ";
  text.replace(text.find(tail), tail.size(), "1.86359e-06 ");
  write_text(dir / "short.dump", text);
  const std::string msg = error_of(dir / "short.dump");
  EXPECT_NE(msg.find("short.dump:11:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("7 values, expected 12"), std::string::npos) << msg;
}

TEST(DumpReaderErrors, NonNumericValue) {
  TempDir dir;
  std::string text = kFrame;
  text.replace(text.find("0.00748598"), 10, "0.0074x598");
  write_text(dir / "bad.dump", text);
  const std::string msg = error_of(dir / "bad.dump");
  EXPECT_NE(msg.find("bad.dump:11:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'x'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("0.0074x598"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a number"), std::string::npos) << msg;
}

TEST(DumpReaderErrors, NonPositiveRadius) {
  TempDir dir;
  std::string text = kFrame;
  text.replace(text.find(" 0.0003 "), 8, " -0.0003 ");
  write_text(dir / "a.dump", text);
  const std::string msg = error_of(dir / "a.dump");
  EXPECT_NE(msg.find("a.dump:11:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("> 0"), std::string::npos) << msg;
}

TEST(DumpReaderErrors, MissingFile) {
  TempDir dir;
  const std::string msg = error_of(dir / "nothere.dump.gz");
  EXPECT_NE(msg.find("nothere.dump.gz"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no such file"), std::string::npos) << msg;
  EXPECT_THROW(DumpReader r(dir.path().string()), DumpError);  // a folder
}

TEST(DumpReaderErrors, TruncatedGzip) {
  TempDir dir;
  std::string big;
  for (int i = 0; i < 200; ++i) big += kFrame;
  write_gzip(dir / "full.dump.gz", big);
  std::string bytes = vfe::apps::test::read_text(dir / "full.dump.gz");
  bytes.resize(bytes.size() / 2);
  write_text(dir / "half.dump.gz", bytes);
  const std::string msg = error_of(dir / "half.dump.gz");
  EXPECT_NE(msg.find("half.dump.gz"), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
}

TEST(DumpReaderErrors, NotADumpAndEmptyFile) {
  TempDir dir;
  write_text(dir / "notes.txt", "hello world\n");
  const std::string msg = error_of(dir / "notes.txt");
  EXPECT_NE(msg.find("notes.txt:1:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("ITEM: TIMESTEP"), std::string::npos) << msg;

  write_text(dir / "empty.dump", "");
  const std::string msg2 = error_of(dir / "empty.dump");
  EXPECT_NE(msg2.find("no frame"), std::string::npos) << msg2;
}

// A dump whose last line was cut inside a number (one still being written) was read as
// complete. A last line without a line end must end with a blank (LIGGGHTS writes one).
TEST(DumpReaderErrors, LastLineCutInsideANumberIsAnError) {
  TempDir dir;
  std::string text = kFrame;
  text.resize(text.size() - 2);  // "... 0 0 0 \n" loses its blank and line end: all values
  ASSERT_EQ(text.back(), '0');     // are there, but the last one may have lost digits
  write_text(dir / "cut.dump", text);
  const std::string e = error_of(dir / "cut.dump");
  EXPECT_NE(e.find("cut.dump:12"), std::string::npos) << e;
  EXPECT_NE(e.find("no line end"), std::string::npos) << e;
  // The same cut inside a value line of the header.
  write_text(dir / "cut_header.dump", "ITEM: TIMESTEP\n100\nITEM: NUMBER OF ATOMS\n3");
  EXPECT_NE(error_of(dir / "cut_header.dump").find("no line end"), std::string::npos);
  // A folder is not a dump.
  EXPECT_NE(error_of(dir.path()).find("is a folder"), std::string::npos);
}

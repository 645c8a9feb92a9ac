// Helpers shared by the engine tests: a set of spheres as SoA arrays, grids, a compute.
#pragma once

#include <vfe/engine.hpp>

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace vfe::test {

struct Particles {
  std::vector<double> centres, radii, quats;
  ParticleView view() const {
    ParticleView v;
    v.n = static_cast<std::int64_t>(radii.size());
    v.centres = centres.data();
    v.radii = radii.data();
    v.orientations = quats.empty() ? nullptr : quats.data();
    return v;
  }
  double volume() const {
    double s = 0;
    for (double r : radii) s += 4.0 / 3.0 * std::numbers::pi * r * r * r;
    return s;
  }
  void add(double x, double y, double z, double r) {
    centres.insert(centres.end(), {x, y, z});
    radii.push_back(r);
  }
};

/// nx x ny x nz cubic cells of size h from the origin.
inline CartesianGridSpec grid(double h, std::int64_t nx, std::int64_t ny, std::int64_t nz) {
  CartesianGridSpec g;
  g.origin = {0, 0, 0};
  g.spacing = {h, h, h};
  g.cells = {nx, ny, nz};
  return g;
}

/// e's compute of p into out must fail with `status` and a message holding `text`.
inline void expect_compute_fails(Engine& e, const Particles& p, std::vector<double>& out, vfe_status status,
                                 const std::string& text) {
  try {
    e.compute(p.view(), out);
    ADD_FAILURE() << "the compute was accepted; expected an error with \"" << text << "\"";
  } catch (const Error& err) {
    EXPECT_EQ(err.status(), status);
    EXPECT_NE(std::string(err.what()).find(text), std::string::npos) << err.what();
  }
}

/// Configures e and returns its solid-volume field for p.
inline std::vector<double> run(Engine& e, const Particles& p, const std::string& options) {
  e.configure(options);
  std::vector<double> out(e.cell_count(), -1.0);
  e.compute(p.view(), out);
  return out;
}

#ifdef VFE_SOURCE_DIR
/// x y z radius of the settled LIGGGHTS bed in data/liggghts (columns 3-6 of the dump); at
/// most `limit` particles.
inline Particles packed_bed(std::size_t limit = 20000) {
  gzFile f = gzopen(VFE_SOURCE_DIR "/data/liggghts/bed_mono_final.dump.gz", "rb");
  EXPECT_NE(f, nullptr);
  Particles p;
  char line[512];
  bool atoms = false;
  while (f && p.radii.size() < limit && gzgets(f, line, sizeof line)) {
    if (std::string(line).rfind("ITEM: ATOMS", 0) == 0) {
      atoms = true;
      continue;
    }
    if (!atoms) continue;
    std::istringstream in(line);
    double id, type, x, y, z, r;
    if (in >> id >> type >> x >> y >> z >> r) p.add(x, y, z, r);
  }
  if (f) gzclose(f);
  return p;
}
#endif

/// n spheres with centres uniform in [lo, hi)^3 and radii uniform in [rmin, rmax) (seeded).
inline Particles random_spheres(std::uint32_t seed, int n, double lo, double hi, double rmin, double rmax) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pos(lo, hi), rad(rmin, rmax);
  Particles p;
  for (int i = 0; i < n; ++i) {
    const double x = pos(rng), y = pos(rng), z = pos(rng);
    p.add(x, y, z, rad(rng));
  }
  return p;
}

/// Sum of |a - b| over the cells.
inline double l1(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += std::abs(a[i] - b[i]);
  return s;
}

inline double total(const std::vector<double>& f) {
  double s = 0;
  for (double x : f) s += x;
  return s;
}

}  // namespace vfe::test

// Shape templates through the public API: build time and accuracy per shape.
//   BM_template_build/<shape>/<n>: a fresh engine, add_shape, one pmm compute of one particle
//     at particle_grid=n (so the time is the template's sampling and cutting plus one
//     particle's deposit); time per iteration.
//   counters l1, max_err: the particle's solid field at particle_grid=n against
//     particle_grid=20000 (l1 = sum |Vs - Vs_ref| / particle volume; max_err = max |deps|).
// One particle of volume-equivalent diameter 1 on a grid of cubes of side 1 (chi = 1), off
// the cell corners, turned by a fixed quaternion; one thread.

#include <vfe/engine.hpp>
#include <vfe/measures.hpp>

#include <benchmark/benchmark.h>

#include <cmath>
#include <exception>
#include <numbers>
#include <string>
#include <vector>

#ifndef VFE_SOURCE_DIR
#error "VFE_SOURCE_DIR must be defined (the project's source folder)"
#endif

namespace {

struct NamedShape {
  const char* name;
  std::string spec;
};

const std::vector<NamedShape>& shapes() {
  static const std::vector<NamedShape> s = {
      {"ellipsoid", "ellipsoid 1 0.6 0.4"},
      {"superquadric", "superquadric 1 0.8 0.6 0.4 0.4"},
      {"clump3", "clump -0.6 0 0 0.5; 0 0 0 0.6; 0.6 0 0 0.5"},
      {"cube_mesh", "mesh " VFE_SOURCE_DIR "/data/shapes/cube.obj"},
  };
  return s;
}

vfe::CartesianGridSpec grid() {
  vfe::CartesianGridSpec g;
  g.origin = {-4, -4, -4};
  g.spacing = {1, 1, 1};
  g.cells = {8, 8, 8};
  return g;
}

/// Solid field of one particle of the shape at particle_grid=n; volume gets the particle's.
std::vector<double> field(const std::string& spec, long n, double* volume = nullptr) {
  vfe::Engine e(grid());
  e.configure("threads=1 method=pmm orientation=given particle_grid=" + std::to_string(n));
  const std::int32_t id = e.add_shape(spec);
  const double scale = 1.0 / std::cbrt(6.0 * e.shape_volume(id) / std::numbers::pi);
  static const double centre[3] = {0.13, 0.29, -0.37};
  static const double q[4] = {0.8, 0.2, -0.4, 0.4};  // |q| = 1
  vfe::ParticleView pv;
  pv.n = 1;
  pv.centres = centre;
  pv.radii = &scale;
  pv.orientations = q;
  pv.shape_ids = &id;
  std::vector<double> out(static_cast<std::size_t>(e.cell_count()));
  e.compute(pv, out);
  if (volume) *volume = e.last_report().particle_volume;
  return out;
}

void bench_build(benchmark::State& state, const NamedShape& shape) {
  try {
    const long n = static_cast<long>(state.range(0));
    for (auto _ : state) {
      std::vector<double> f = field(shape.spec, n);
      benchmark::DoNotOptimize(f.data());
    }
    double vp = 0;
    const std::vector<double> a = field(shape.spec, n, &vp);
    const std::vector<double> ref = field(shape.spec, 20000);
    const std::vector<double> vc(a.size(), 1.0);
    const vfe::AccuracyMeasures m = vfe::compare_fields(a, ref, vc, vp);
    state.counters["l1"] = m.l1;
    state.counters["max_err"] = m.max_error;
    state.counters["vol_err"] = m.volume_error;
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  for (const NamedShape& s : shapes())
    benchmark::RegisterBenchmark((std::string("BM_template_build/") + s.name).c_str(),
                                 [&s](benchmark::State& st) { bench_build(st, s); })
        ->Arg(125)
        ->Arg(1000)
        ->Unit(benchmark::kMillisecond);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

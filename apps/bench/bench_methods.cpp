// Throughput of the methods on the settled packed bed (20000 spheres of 1 mm) on the
// 2 mm and 1 mm grids, with one thread and with all threads; and the same exact volumes by a
// general sphere-polyhedron overlap per cut cell, as general exact-overlap codes compute them.
//   items_per_second = particles per second; sub_elements/s from the engine's report.

#include "dump_reader.hpp"

#include <vfe/engine.hpp>
#include <vfe/kernels/sphere_polyhedron_overlap.hpp>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#ifndef VFE_SOURCE_DIR
#error "VFE_SOURCE_DIR must be defined (the project's source folder)"
#endif

namespace {

const vfe::apps::DumpFrame& packed_bed() {
  static const vfe::apps::DumpFrame frame =
      vfe::apps::read_dump_frame(VFE_SOURCE_DIR "/data/liggghts/bed_mono_final.dump.gz");
  return frame;
}

/// The dump's box cut into cubes of side h.
vfe::CartesianGridSpec grid_on_box(const vfe::apps::DumpFrame& f, double h) {
  vfe::CartesianGridSpec g;
  for (int d = 0; d < 3; ++d) {
    const double len = f.box[2 * d + 1] - f.box[2 * d];
    g.origin[d] = f.box[2 * d];
    g.cells[d] = std::max<std::int64_t>(1, std::llround(len / h));
    g.spacing[d] = len / static_cast<double>(g.cells[d]);
  }
  return g;
}

void bench_method(benchmark::State& state, const std::string& options, double h, int threads) {
  try {
    const auto& frame = packed_bed();
    vfe::Engine engine(grid_on_box(frame, h));
    engine.configure(options + " threads=" + std::to_string(threads));
    std::vector<double> solid(static_cast<std::size_t>(engine.cell_count()));
    const vfe::ParticleView view = frame.view();
    engine.compute(view, solid);  // warm-up
    for (auto _ : state) {
      engine.compute(view, solid);
      benchmark::DoNotOptimize(solid.data());
      benchmark::ClobberMemory();
    }
    const vfe::Report& rep = engine.last_report();
    const auto iters = static_cast<double>(state.iterations());
    state.SetItemsProcessed(state.iterations() * frame.n);
    state.counters["sub_elements/s"] =
        benchmark::Counter(static_cast<double>(rep.sub_elements) * iters, benchmark::Counter::kIsRate);
    state.counters["grid_min"] = static_cast<double>(rep.particle_grid_min);
    state.counters["grid_max"] = static_cast<double>(rep.particle_grid_max);
    state.counters["threads"] = threads;
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}

/// What a general exact-overlap code does on a Cartesian grid: for every sphere, every cell
/// its bounding box reaches, an exact sphere-polyhedron overlap of that hexahedron
/// (kernels::sphere_polyhedron_overlap, six quadrilaterals). One thread, items = spheres; the comparison
/// for the closed-form box overlaps of method=exact (methods/exact/<grid>/threads:1).
void bench_general_exact(benchmark::State& state, double h) {
  const auto& frame = packed_bed();
  const vfe::CartesianGridSpec g = grid_on_box(frame, h);
  const std::int32_t quads[] = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
  const std::int32_t offsets[] = {0, 4, 8, 12, 16, 20, 24};
  std::int64_t cut_cells = 0;
  double total = 0;
  for (auto _ : state) {
    cut_cells = 0;
    total = 0;
    for (std::int64_t p = 0; p < frame.n; ++p) {
      const Eigen::Vector3d c(frame.centres[3 * p], frame.centres[3 * p + 1], frame.centres[3 * p + 2]);
      const double r = frame.radii[p];
      std::int64_t lo[3], hi[3];
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((c[d] - r - g.origin[d]) / g.spacing[d])));
        hi[d] = std::min<std::int64_t>(g.cells[d] - 1,
                                       static_cast<std::int64_t>(std::floor((c[d] + r - g.origin[d]) / g.spacing[d])));
      }
      for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
        for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
          for (std::int64_t i = lo[0]; i <= hi[0]; ++i) {
            std::array<Eigen::Vector3d, 8> v;
            for (int q = 0; q < 8; ++q)
              v[q] = Eigen::Vector3d(g.origin[0] + g.spacing[0] * double(i + (q & 1)),
                                     g.origin[1] + g.spacing[1] * double(j + ((q >> 1) & 1)),
                                     g.origin[2] + g.spacing[2] * double(k + ((q >> 2) & 1)));
            total += vfe::kernels::sphere_polyhedron_overlap(c, r, v, offsets, quads);
            ++cut_cells;
          }
    }
    benchmark::DoNotOptimize(total);
  }
  state.SetItemsProcessed(state.iterations() * frame.n);
  state.counters["cells_per_sphere"] = double(cut_cells) / double(frame.n);
}

}  // namespace

int main(int argc, char** argv) {
  struct Method {
    const char* label;
    const char* options;
  };
  const Method methods[] = {{"direct", "method=direct"},
                            {"pmm_auto", "method=pmm particle_grid=auto"},
                            {"pmm_125", "method=pmm particle_grid=125"},
                            {"exact", "method=exact"}};
  struct Grid {
    const char* label;
    double h;
  };
  const Grid grids[] = {{"2mm", 0.002}, {"1mm", 0.001}};
  const int all = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<int> thread_counts = {1};
  if (all > 1) thread_counts.push_back(all);

  for (const auto& g : grids)
    for (const auto& m : methods)
      for (int t : thread_counts) {
        const std::string name = std::string("methods/") + m.label + "/" + g.label + "/threads:" + std::to_string(t);
        const std::string options = m.options;
        const double h = g.h;
        benchmark::RegisterBenchmark(name.c_str(), [options, h, t](benchmark::State& s) { bench_method(s, options, h, t); })
            ->UseRealTime()
            ->Unit(benchmark::kMillisecond);
      }

  for (const auto& g : grids) {
    const double h = g.h;
    benchmark::RegisterBenchmark((std::string("general_exact_hexahedra/") + g.label + "/threads:1").c_str(),
                                 [h](benchmark::State& s) { bench_general_exact(s, h); })
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
  }

  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

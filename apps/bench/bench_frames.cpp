// Incremental update on a real settling bed: the 20 LIGGGHTS frames of 1 mm spheres poured
// in batches into a 20 x 20 x 60 mm box (data/liggghts/bed_mono_frames, 2500 to 20000
// particles), computed in order on the 2 mm grid as a coupled run would: full computes
// (tolerance_um:-1) against incremental=1 with a move tolerance of 0, 1 or 10 um. One iteration = the whole sequence (or only its settled part, the last 10
// frames with all 20000 particles).
//   counters: frames_per_s, moved = fraction of particles computed anew,
//   l1_vs_full = L1 distance of the last frame's field from a full compute / particle volume.

#include "dump_reader.hpp"

#include <vfe/engine.hpp>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

#ifndef VFE_SOURCE_DIR
#error "VFE_SOURCE_DIR must be defined (the project's source folder)"
#endif

namespace {

/// The frames in time order, particles sorted by id (the engine matches particles by index).
const std::vector<vfe::apps::DumpFrame>& frames() {
  static const std::vector<vfe::apps::DumpFrame> all = [] {
    std::vector<vfe::apps::DumpFrame> out;
    for (const auto& entry : std::filesystem::directory_iterator(VFE_SOURCE_DIR "/data/liggghts/bed_mono_frames"))
      out.push_back(vfe::apps::read_dump_frame(entry.path().string()));
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.timestep < b.timestep; });
    for (auto& f : out) {
      if (f.ids.empty()) continue;
      std::vector<std::size_t> order(static_cast<std::size_t>(f.n));
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return f.ids[a] < f.ids[b]; });
      std::vector<double> c(f.centres.size()), r(f.radii.size());
      for (std::size_t i = 0; i < order.size(); ++i) {
        for (int d = 0; d < 3; ++d) c[3 * i + d] = f.centres[3 * order[i] + d];
        r[i] = f.radii[order[i]];
      }
      f.centres.swap(c);
      f.radii.swap(r);
    }
    return out;
  }();
  return all;
}

vfe::ParticleView view(const vfe::apps::DumpFrame& f) {
  vfe::ParticleView v;
  v.n = f.n;
  v.centres = f.centres.data();
  v.radii = f.radii.data();
  return v;
}

/// The box of the dumps in 2 mm cubes (chi = 2).
vfe::CartesianGridSpec grid_2mm() {
  vfe::CartesianGridSpec g;
  g.origin = {0, 0, 0};
  g.spacing = {0.002, 0.002, 0.002};
  g.cells = {10, 10, 30};
  return g;
}

/// range(0): -1 = full compute, else incremental=1 with a move tolerance of range(0)
/// micrometres (1 um = 1e-3 diameters); range(1): 1 = settled frames only.
void Frames(benchmark::State& state, const std::string& method, int threads) {
  const std::int64_t tolerance_um = state.range(0);
  const bool settled = state.range(1) == 1;
  const auto& all = frames();
  const std::size_t first = settled ? all.size() - 10 : 0;
  vfe::Engine e(grid_2mm()), full(grid_2mm());
  const std::string base = method + " threads=" + std::to_string(threads);
  e.configure(base + (tolerance_um < 0 ? std::string()
                                       : " incremental=1 move_tolerance=" + std::to_string(double(tolerance_um) * 1e-6)));
  full.configure(base);
  std::vector<double> field(static_cast<std::size_t>(e.cell_count())), reference(field.size());
  double moved = 0, particles = 0;
  for (auto _ : state) {
    for (std::size_t k = first; k < all.size(); ++k) {
      e.compute(view(all[k]), field);
      moved += e.last_report_value("moved_particles");
      particles += double(all[k].n);
    }
  }
  full.compute(view(all.back()), reference);
  double l1 = 0;
  for (std::size_t c = 0; c < field.size(); ++c) l1 += std::abs(field[c] - reference[c]);
  state.counters["frames_per_s"] =
      benchmark::Counter(double(all.size() - first), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["moved"] = moved / particles;
  state.counters["l1_vs_full"] = l1 / full.last_report().particle_volume;
  state.SetItemsProcessed(static_cast<std::int64_t>(particles));
}

void register_all() {
  for (const char* method : {"pmm", "exact"})
    for (const int threads : {1, 2}) {
      const std::string m = std::string("method=") + method;
      benchmark::RegisterBenchmark((std::string("frames/") + method + "/threads:" + std::to_string(threads)).c_str(),
                                   [m, threads](benchmark::State& s) { Frames(s, m, threads); })
          ->ArgsProduct({{-1, 0, 1, 10}, {0, 1}})
          ->ArgNames({"tolerance_um", "settled"})
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
}

}  // namespace

int main(int argc, char** argv) {
  register_all();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

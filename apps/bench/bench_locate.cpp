// Point location throughput on the four OpenFOAM meshes (one thread): spatial hash,
// KD-tree and neighbour walk, on random points inside the mesh and on points clustered
// like the sub-elements of 1 mm particles (64 per particle).
//   items_per_second = located points per second.
//   *_random:    uniform points inside the mesh, in random order; the walk starts from
//                the previous point's cell (a cold walk across the mesh).
//   *_clustered: per particle, its centre is located with the hash and each sub-element
//                from the centre's cell (the walk) or from scratch (hash, KD-tree).
// A benchmark of engine internals: it includes engine/src/polymesh headers.

#include "polymesh/locators.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Core>

#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#ifndef VFE_SOURCE_DIR
#error "VFE_SOURCE_DIR must be defined (the project's source folder)"
#endif

namespace {

constexpr int kSubElements = 64;
constexpr double kParticleDiameter = 0.001;

struct Scene {
  vfe::PolyMesh mesh;
  std::unique_ptr<vfe::CellLocator> locator;
  std::vector<Eigen::Vector3d> random;  // inside the mesh
  std::vector<Eigen::Vector3d> centres;
  std::vector<Eigen::Vector3d> subs;  // kSubElements per centre, particle by particle

  explicit Scene(const std::string& name)
      : mesh(vfe::PolyMesh::read(std::string(VFE_SOURCE_DIR) + "/data/openfoam/" + name)) {
    locator = std::make_unique<vfe::CellLocator>(mesh);
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0, 1);
    const Eigen::Vector3d lo = mesh.bounds().min(), size = mesh.bounds().sizes();
    const auto inside_point = [&] {
      for (;;) {
        const Eigen::Vector3d p = lo + Eigen::Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(size);
        if (locator->locate(p) >= 0) return p;
      }
    };
    for (int i = 0; i < 50000; ++i) random.push_back(inside_point());
    // Particles whose sub-elements all lie inside the mesh (as in a settled bed).
    while (centres.size() < 2000) {
      const Eigen::Vector3d c = inside_point();
      std::vector<Eigen::Vector3d> s;
      while (s.size() < kSubElements) {
        const Eigen::Vector3d d(2 * u(rng) - 1, 2 * u(rng) - 1, 2 * u(rng) - 1);
        if (d.squaredNorm() <= 1) s.push_back(c + 0.5 * kParticleDiameter * d);
      }
      bool inside = true;
      for (const auto& p : s) inside = inside && locator->locate(p) >= 0;
      if (!inside) continue;
      centres.push_back(c);
      subs.insert(subs.end(), s.begin(), s.end());
    }
  }
};

const Scene& scene(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Scene>> cache;
  auto& slot = cache[name];
  if (!slot) slot = std::make_unique<Scene>(name);
  return *slot;
}

void hash_random(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  for (auto _ : state)
    for (const auto& p : s.random) benchmark::DoNotOptimize(s.locator->hash().locate(p));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.random.size()));
}

void kdtree_random(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  for (auto _ : state)
    for (const auto& p : s.random) benchmark::DoNotOptimize(s.locator->kdtree().locate(p));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.random.size()));
}

void walk_random(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  std::int64_t fallbacks = 0, steps = 0;
  for (const auto& p : s.random) {
    const auto r = s.locator->walk().walk(p, 0);
    fallbacks += r.stop != vfe::NeighbourWalk::Stop::kInside;
    steps += r.steps;
  }
  for (auto _ : state) {
    std::int64_t c = 0;
    for (const auto& p : s.random) {
      c = s.locator->locate_from(p, c);
      benchmark::DoNotOptimize(c);
    }
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.random.size()));
  state.counters["fallback_from_cell_0"] = double(fallbacks) / double(s.random.size());
  state.counters["steps_from_cell_0"] = double(steps) / double(s.random.size());
}

template <class Locate>
void clustered(benchmark::State& state, const Scene& s, Locate&& locate) {
  for (auto _ : state) {
    const Eigen::Vector3d* p = s.subs.data();
    for (const auto& c : s.centres) {
      const std::int64_t home = s.locator->locate(c);
      for (int k = 0; k < kSubElements; ++k, ++p) benchmark::DoNotOptimize(locate(*p, home));
    }
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.subs.size()));
}

void hash_clustered(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  clustered(state, s, [&](const Eigen::Vector3d& p, std::int64_t) { return s.locator->hash().locate(p); });
}

void kdtree_clustered(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  clustered(state, s, [&](const Eigen::Vector3d& p, std::int64_t) { return s.locator->kdtree().locate(p); });
}

void walk_clustered(benchmark::State& state, const std::string& name) {
  const Scene& s = scene(name);
  std::int64_t fallbacks = 0, steps = 0;
  const Eigen::Vector3d* p = s.subs.data();
  for (const auto& c : s.centres) {
    const std::int64_t home = s.locator->locate(c);
    for (int k = 0; k < kSubElements; ++k, ++p) {
      const auto r = s.locator->walk().walk(*p, home);
      fallbacks += r.stop != vfe::NeighbourWalk::Stop::kInside;
      steps += r.steps;
    }
  }
  clustered(state, s, [&](const Eigen::Vector3d& q, std::int64_t home) { return s.locator->locate_from(q, home); });
  state.counters["fallback"] = double(fallbacks) / double(s.subs.size());
  state.counters["steps"] = double(steps) / double(s.subs.size());
}

void exact_test(benchmark::State& state, const std::string& name) {
  // The exact point-in-cell test alone, on the cell that holds the point.
  const Scene& s = scene(name);
  std::vector<std::int64_t> cells;
  for (const auto& p : s.random) cells.push_back(s.locator->locate(p));
  for (auto _ : state)
    for (std::size_t i = 0; i < s.random.size(); ++i)
      benchmark::DoNotOptimize(vfe::cell_contains(s.mesh, cells[i], s.random[i]));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.random.size()));
}

#define VFE_LOCATE_BENCH(fn)                                                            \
  BENCHMARK_CAPTURE(fn, box_uniform, std::string("box_uniform_10x10x30"))->Unit(benchmark::kMillisecond); \
  BENCHMARK_CAPTURE(fn, box_graded, std::string("box_graded"))->Unit(benchmark::kMillisecond);           \
  BENCHMARK_CAPTURE(fn, cylinder, std::string("cylinder_ogrid_coarse"))->Unit(benchmark::kMillisecond);  \
  BENCHMARK_CAPTURE(fn, snappy, std::string("snappy_obstacle"))->Unit(benchmark::kMillisecond);

VFE_LOCATE_BENCH(exact_test)
VFE_LOCATE_BENCH(hash_random)
VFE_LOCATE_BENCH(kdtree_random)
VFE_LOCATE_BENCH(walk_random)
VFE_LOCATE_BENCH(hash_clustered)
VFE_LOCATE_BENCH(kdtree_clustered)
VFE_LOCATE_BENCH(walk_clustered)

}  // namespace

BENCHMARK_MAIN();

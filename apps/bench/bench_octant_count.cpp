// pmm's octant count alone (kernels/octant_split.hpp): one batch call per 256 particles of
// one set of split axes, each with a random rotation from the bank and random thresholds,
// for templates from the 45 points method=auto takes at chi = 2 to 4000 (815 at chi = 1),
// each counting code's sizes; the fastest code the CPU runs, the portable one, and the
// counts from the bank's projections (templates of at most 64 points). Time per
// particle counted; and the time to build the projections.
#include <vfe/kernels/octant_split.hpp>
#include <vfe/kernels/particle_template.hpp>

#include <benchmark/benchmark.h>

#include <cstdint>
#include <random>
#include <vector>

namespace {

using vfe::kernels::OctantQuery;

void count_batches(benchmark::State& state, vfe::kernels::SplitPath path, bool projected = false) {
  vfe::kernels::ParticleTemplate t = vfe::kernels::make_fibonacci_template(static_cast<int>(state.range(0)));
  vfe::kernels::prepare_octant_split(t);
  const auto split = static_cast<unsigned>(state.range(1));
  const vfe::kernels::OctantCounter& counter = vfe::kernels::octant_counter(t, path);
  const float* bank = vfe::kernels::banked_rotation_rows_table();
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<float> offset(-0.8f, 0.8f);  // planes through the template
  constexpr std::size_t kBatch = 256, kQueries = 1 << 16;
  const vfe::kernels::BankProjections projections =
      projected ? vfe::kernels::project_on_rotation_bank(t) : vfe::kernels::BankProjections{};
  std::vector<OctantQuery> queries(kQueries);
  for (OctantQuery& q : queries) {
    const std::size_t slot = rng() % vfe::kernels::kRotationBankSize;
    q.rotation = projected ? projections.of_slot(slot) : bank + 9 * slot;
    for (float& tau : q.tau) tau = offset(rng);
  }
  const vfe::kernels::OctantBatchFn batch =
      (projected ? counter.projected_batch_by_split : counter.batch_by_split)[split];
  std::vector<std::int32_t> counts(8 * kBatch);
  std::vector<std::uint8_t> decided(kBatch);
  std::size_t next = 0;
  for (auto _ : state) {
    batch(t, queries.data() + next, kBatch, counts.data(), decided.data());
    benchmark::DoNotOptimize(counts.data());
    benchmark::DoNotOptimize(decided.data());
    next = (next + kBatch) % kQueries;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kBatch));
  // Seconds per particle counted.
  state.counters["per_count"] = benchmark::Counter(double(kBatch), benchmark::Counter::kIsIterationInvariantRate |
                                                                       benchmark::Counter::kInvert);
}

void fastest(benchmark::State& state) { count_batches(state, vfe::kernels::SplitPath::fastest); }
void portable(benchmark::State& state) { count_batches(state, vfe::kernels::SplitPath::portable); }
// The same counts from the template's projections on the rotation bank (at most 64 points).
void projected(benchmark::State& state) { count_batches(state, vfe::kernels::SplitPath::fastest, true); }

// Building a template's projections on the bank (once per engine and template).
void build_projections(benchmark::State& state) {
  vfe::kernels::ParticleTemplate t = vfe::kernels::make_fibonacci_template(static_cast<int>(state.range(0)));
  vfe::kernels::prepare_octant_split(t);
  for (auto _ : state) benchmark::DoNotOptimize(vfe::kernels::project_on_rotation_bank(t).values.get());
}

// Arguments: template points, split set (1: x, 3: x and y, 7: all three axes).
BENCHMARK(fastest)->ArgsProduct({{45, 130, 400, 815, 2000, 4000}, {1, 3, 7}});
BENCHMARK(portable)->ArgsProduct({{45, 815}, {1, 7}});
BENCHMARK(projected)->ArgsProduct({{45, 64}, {1, 3, 7}});
BENCHMARK(build_projections)->Arg(45)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

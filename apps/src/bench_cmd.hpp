// `vfe bench`: throughput of the engine's methods on generated particle scenes (a packed
// bed or a dilute stream, 1e4 to a few 1e6 particles), with memory per particle and per
// cell, the 1 -> 2 thread speed-up and two limits measured in the same run: a
// memory-bandwidth bound and a minimal PMM locate loop.
#pragma once

#include "cli_command.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace spdlog {
class logger;
}

namespace vfe::apps {

struct BenchCommand {
  std::string scene = "bed";       ///< bed (packed, solid fraction 0.58) or stream (dilute, 0.05)
  std::string dispersity = "mono"; ///< mono (diameter 1) or poly (uniform in [0.7, 1.3])
  std::string order = "shuffled";  ///< the particles' order: shuffled (a DEM code's after rebuilds) or morton
  std::vector<double> particles{1e4, 1e5};
  std::vector<double> chi{2.0};    ///< cell size / mean diameter
  std::vector<int> threads{1, 2};  ///< 0 = all
  std::vector<std::string> methods{"direct", "pmm", "exact"};  ///< engine methods; {"all"} = every engine method
  std::string particle_grid = "auto";
  std::string options;             ///< more engine options, "key=value ..."
  std::vector<std::string> particle_orders;  ///< engine particle_order values, timed alternately; empty: the default
  int repeats = 3;                 ///< timed computes after one warm-up (the median is reported)
  std::uint64_t seed = 1;
  bool limits = true;  ///< also measure the bandwidth and locate limits
  std::filesystem::path output = "bench";
  std::shared_ptr<spdlog::logger> logger;  ///< progress; null = quiet
  std::ostream* table = nullptr;           ///< where the table goes; null = none
};

/// A generated scene: particle order shuffled, diameters with mean about 1.
struct BenchScene {
  std::string name, dispersity;
  std::int64_t n = 0;
  std::vector<double> centres;  ///< 3n
  std::vector<double> radii;    ///< n
  std::array<double, 3> lo{0, 0, 0}, hi{0, 0, 0};  ///< the scene's box (the bed or the stream)
  double mean_diameter = 0;
  double particle_volume = 0;
  double solid_fraction = 0;  ///< particle_volume / box volume
};

/// bed: a jittered face-centred cubic lattice filled from the bottom (solid fraction 0.58);
/// stream: centres uniform in a cube (0.05). Deterministic for a seed on every platform.
/// Throws std::invalid_argument naming the bad value.
BenchScene make_bench_scene(const std::string& scene, const std::string& dispersity, std::int64_t n,
                            std::uint64_t seed);

/// Reorders the scene's particles along a Morton (Z-order) curve of their centres, 2^21
/// steps per axis over the scene's box: neighbours in space become neighbours in memory.
void sort_morton(BenchScene& scene);

/// One (particles, chi, threads, method) timing.
struct BenchRow {
  std::string scene, dispersity, method;
  std::string order;    ///< shuffled or morton
  std::string options;  ///< the engine's full option string
  std::string particle_order;      ///< the engine's particle_order option
  std::int64_t ordered_blocks = 0; ///< the report fact: slabs the particles were ordered by (0: the host's order)
  std::int64_t particles = 0;
  double chi = 0, cell_size = 0, solid_fraction = 0;
  std::array<std::int64_t, 3> grid{0, 0, 0};
  std::int64_t cells = 0;
  int threads = 0, repeats = 0;
  double time_median_ms = 0, time_min_ms = 0, time_max_ms = 0;
  double particles_per_s = 0, sub_elements_per_s = 0, sub_elements_per_particle = 0;
  std::int64_t sub_elements = 0, fast_path_particles = 0, particle_grid_min = 0, particle_grid_max = 0;
  double volume_error = 0;  ///< |deposited + dropped - particle volume| / particle volume
  /// Resident-memory growth (bytes) when creating the engine and over its first compute.
  std::int64_t engine_bytes = 0, compute_bytes = 0;
  double bytes_per_cell = 0;      ///< engine_bytes / cells
  double bytes_per_particle = 0;  ///< compute_bytes / particles
  std::int64_t peak_rss_bytes = 0;  ///< of the process so far
  /// The median over the timed rounds of the 1-thread engine's time / this one's, the two
  /// timed in turn within each round; NaN for a 1-thread row or without one. speedup_min
  /// and speedup_max: the least and greatest of those ratios (the machine's noise).
  double speedup = 0, speedup_min = 0, speedup_max = 0;
  /// The machine's control in the same rounds: the speed-up (as speedup) of a short locate
  /// pass (no serial part, no shared writes) timed after the engines in every round; NaN
  /// for a 1-thread row, without a 1-thread count or without the limits.
  double control_speedup = 0;
  /// The median over the timed rounds of this engine's time / direct's at the same thread
  /// count and particle order in the same round (1 for direct itself); NaN without direct
  /// among the methods.
  double direct_ratio = 0;
  /// The limits at the same (scene, N, chi, threads) and time_median_ms as a multiple of each.
  double bandwidth_ms = 0, store_ms = 0, scatter_ms = 0, locate_ms = 0;
  double x_bandwidth = 0, x_store = 0, x_scatter = 0, x_locate = 0;
};

/// The limits of one (particles, chi, threads).
struct BenchLimit {
  std::int64_t particles = 0;
  double chi = 0;
  int threads = 0;
  std::int64_t cells = 0;
  double bandwidth_ms = 0;  ///< read centres and radii, clear the cell field
  std::int64_t bandwidth_bytes = 0;
  /// direct's floor: read each centre and radius, add the volume to the centre's cell.
  double store_ms = 0;
  /// Every sub-element of pmm's template for each particle: its cell index, then its volume
  /// added to the field (scatter) or only the indices summed (locate).
  double scatter_ms = 0, locate_ms = 0;
  std::int64_t locate_sub_elements = 0;
  std::int64_t locate_templates = 0;  ///< distinct template sizes the scene needs
  /// Each limit's 1-thread time / this one's, the median of ratios within a round (as
  /// BenchRow::speedup); NaN for one thread or without a 1-thread count. The control for
  /// the methods' speed-ups: what the machine gives a loop with no serial part.
  double bandwidth_speedup = 0, store_speedup = 0, scatter_speedup = 0, locate_speedup = 0;
};

struct BenchOutcome {
  std::vector<BenchRow> rows;
  std::vector<BenchLimit> limits;
  std::int64_t peak_rss_bytes = 0;
  std::filesystem::path output;  ///< folder holding bench.csv, limits.csv and bench.json
};

/// Runs the bench; writes bench.csv, limits.csv, bench.json and prints the table. Throws
/// std::invalid_argument naming the bad argument (--chi, --scene, ...), vfe::Error from
/// the engine (an unknown --options key) or std::runtime_error (output not writable).
BenchOutcome run_bench(const BenchCommand& command);

/// Adds `vfe bench` and its options to the tool (help text and checks included).
CliCommand register_bench(CLI::App& app);

}  // namespace vfe::apps

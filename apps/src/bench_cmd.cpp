#include "bench_cmd.hpp"
#include "engine_methods.hpp"
#include "random.hpp"
#include "report.hpp"
#include "run.hpp"
#include "timing.hpp"

#include <CLI/CLI.hpp>
#include <vfe/engine.hpp>
#include <vfe/kernels/particle_template.hpp>
#include <vfe/vfe.h>

#include <spdlog/logger.h>
#include <spdlog/sinks/null_sink.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <sys/resource.h>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <variant>
#include <iostream>
#include <memory>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;
using kernels::ParticleTemplate;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kBedFraction = 0.58;
constexpr double kStreamFraction = 0.05;
/// Poly diameters are uniform in [1 - kPolySpread, 1 + kPolySpread] (mean 1).
constexpr double kPolySpread = 0.3;
/// More cells than this is a mistake (chi far too small for the scene), not a benchmark.
constexpr double kMaxCells = 2e9;

// --- resident memory -----------------------------------------------------------------

/// Resident set size from /proc/self/statm; -1 where there is none.
std::int64_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  long long size = 0, resident = 0;
  if (!(statm >> size >> resident)) return -1;
  return static_cast<std::int64_t>(resident) * sysconf(_SC_PAGESIZE);
}

std::int64_t peak_resident_bytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return -1;
  return static_cast<std::int64_t>(usage.ru_maxrss) * 1024;  // Linux: kilobytes
}

/// One malloc arena for every thread: malloc_trim cannot shrink the top of a worker
/// thread's own arena, so memory a worker freed (an earlier engine's private field) would be
/// reused unseen by the next row.
void share_one_malloc_arena() {
#if defined(__GLIBC__)
  mallopt(M_ARENA_MAX, 1);
#endif
}

/// Gives freed heap pages back before a baseline, so memory freed by earlier rows and
/// reused by the next one does not hide its growth.
void return_free_memory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

// --- arguments -----------------------------------------------------------------------

[[noreturn]] void bad_argument(const std::string& what) { throw std::invalid_argument(what); }

std::string number_text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

void check_scene_kind(const std::string& scene, const std::string& dispersity) {
  if (scene != "bed" && scene != "stream")
    bad_argument("--scene: unknown scene '" + scene + "'; expected bed or stream");
  if (dispersity != "mono" && dispersity != "poly")
    bad_argument("--dispersity: unknown value '" + dispersity + "'; expected mono or poly");
}

std::vector<std::int64_t> particle_counts(const std::vector<double>& values) {
  if (values.empty()) bad_argument("--particles: no value; give counts such as 1e4,1e5");
  std::vector<std::int64_t> out;
  for (double x : values) {
    if (!(x >= 1) || x > 1e9 || x != std::floor(x))
      bad_argument("--particles: bad value '" + number_text(x) +
                   "'; expected whole counts from 1 to 1e9 (e.g. 1e4,1e5)");
    out.push_back(static_cast<std::int64_t>(x));
  }
  return out;
}

/// Keys the bench sets itself from its own flags (particle_order: when --particle-order is given).
void check_free_options(const std::string& options, bool with_particle_orders) {
  std::istringstream in(options);
  std::string token;
  while (in >> token) {
    const std::string key = token.substr(0, token.find('='));
    if (key == "method" || key == "threads" || key == "particle_grid" ||
        (key == "particle_order" && with_particle_orders))
      bad_argument("--options: '" + token + "' is set by the bench; use --" +
                   (key == "particle_grid"    ? std::string("particle-grid")
                    : key == "particle_order" ? std::string("particle-order")
                                              : key) +
                   " instead");
  }
}

/// The engine's message with the flag that carried the bad value in front.
void configure_or_throw(vfe::Engine& engine, const std::string& options, const std::string& flag) {
  try {
    engine.configure(options);
  } catch (const vfe::Error& e) {
    throw vfe::Error(e.status(), flag + ": " + e.what());
  }
}

// --- the limits ----------------------------------------------------------------------

/// Where the bandwidth pass's sum goes, so the compiler must do the reads.
volatile double g_sink = 0;

/// Sum with four independent lanes, so the loop streams memory instead of waiting on adds.
double lane_sum(const double* x, std::size_t n) {
  double lane[4] = {0, 0, 0, 0};
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4)
    for (int k = 0; k < 4; ++k) lane[k] += x[i + k];
  for (; i < n; ++i) lane[0] += x[i];
  return (lane[0] + lane[1]) + (lane[2] + lane[3]);
}

/// The least any method must do: read every centre and radius, clear the cell field.
double bandwidth_pass(tbb::task_arena& arena, const BenchScene& s, std::vector<double>& field) {
  return arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, field.size(), 1 << 15),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        std::fill(field.begin() + r.begin(), field.begin() + r.end(), 0.0);
                      });
    return tbb::parallel_reduce(
        tbb::blocked_range<std::int64_t>(0, s.n, 1 << 14), 0.0,
        [&](const tbb::blocked_range<std::int64_t>& r, double acc) {
          const auto b = static_cast<std::size_t>(r.begin()), e = static_cast<std::size_t>(r.end());
          return acc + lane_sum(s.centres.data() + 3 * b, 3 * (e - b)) + lane_sum(s.radii.data() + b, e - b);
        },
        std::plus<>());
  });
}

/// The least direct must do: read each centre and radius and add the sphere's volume to
/// the cell holding its centre, in a field per thread (never merged: a lower bound), the
/// particle stream prefetched (this machine's hardware prefetcher does not follow it).
void store_pass(tbb::task_arena& arena, const BenchScene& s, const vfe::CartesianGridSpec& g,
                tbb::enumerable_thread_specific<std::vector<double>>& fields) {
  const std::size_t ncells = static_cast<std::size_t>(g.cells[0] * g.cells[1] * g.cells[2]);
  const double inv_h = 1.0 / g.spacing[0];  // cubic cells
  const double o0 = g.origin[0], o1 = g.origin[1], o2 = g.origin[2];
  const std::int64_t nx = g.cells[0], nxy = g.cells[0] * g.cells[1];
  const double n0 = double(g.cells[0]), n1 = double(g.cells[1]), n2 = double(g.cells[2]);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, s.n, 4096), [&](const tbb::blocked_range<std::int64_t>& r) {
      std::vector<double>& local = fields.local();
      if (local.size() != ncells) local.assign(ncells, 0.0);
      double* field = local.data();
      const double* centres = s.centres.data();
      const double* radii = s.radii.data();
      for (std::int64_t p = r.begin(); p < r.end(); ++p) {
        __builtin_prefetch(centres + 3 * (p + 16));
        __builtin_prefetch(radii + p + 16);
        const double* c = centres + 3 * p;
        const double t0 = (c[0] - o0) * inv_h, t1 = (c[1] - o1) * inv_h, t2 = (c[2] - o2) * inv_h;
        if (!((t0 >= 0) & (t0 < n0) & (t1 >= 0) & (t1 < n1) & (t2 >= 0) & (t2 < n2))) continue;
        const double radius = radii[p];
        field[static_cast<std::int64_t>(t0) + nx * static_cast<std::int64_t>(t1) + nxy * static_cast<std::int64_t>(t2)] +=
            4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
      }
    });
  });
}

/// The engine's template size for each particle: the size is monotone in the diameter, so
/// bisection finds the diameters where it changes (a handful for a polydisperse scene).
struct TemplateChoice {
  std::vector<ParticleTemplate> templates;
  std::vector<std::uint16_t> of_particle;
  std::int64_t sub_elements = 0;  ///< per pass over the scene
};

TemplateChoice choose_templates(const vfe::Engine& pmm_probe, const BenchScene& s, double cell_size) {
  double d_min = std::numeric_limits<double>::infinity(), d_max = 0;
  for (double r : s.radii) {
    d_min = std::min(d_min, 2 * r);
    d_max = std::max(d_max, 2 * r);
  }
  std::vector<double> starts{d_min};  // sizes[i] from diameter starts[i] on
  std::vector<std::int64_t> sizes{pmm_probe.particle_grid_for(d_min, cell_size)};
  const std::function<void(double, std::int64_t, double, std::int64_t)> split = [&](double lo, std::int64_t n_lo,
                                                                                     double hi, std::int64_t n_hi) {
    if (n_lo == n_hi) return;
    if (hi - lo <= 1e-12 * hi) {
      starts.push_back(hi);
      sizes.push_back(n_hi);
      return;
    }
    const double mid = 0.5 * (lo + hi);
    const std::int64_t n_mid = pmm_probe.particle_grid_for(mid, cell_size);
    split(lo, n_lo, mid, n_mid);
    split(mid, n_mid, hi, n_hi);
  };
  split(d_min, sizes[0], d_max, pmm_probe.particle_grid_for(d_max, cell_size));
  if (sizes.size() > std::numeric_limits<std::uint16_t>::max()) throw std::runtime_error("too many template sizes");

  TemplateChoice c;
  for (std::int64_t n : sizes) c.templates.push_back(kernels::make_fibonacci_template(static_cast<int>(n)));
  c.of_particle.resize(static_cast<std::size_t>(s.n));
  for (std::int64_t p = 0; p < s.n; ++p) {
    const auto i = std::upper_bound(starts.begin(), starts.end(), 2 * s.radii[p]) - starts.begin() - 1;
    c.of_particle[p] = static_cast<std::uint16_t>(std::max<std::ptrdiff_t>(i, 0));
    c.sub_elements += static_cast<std::int64_t>(c.templates[c.of_particle[p]].size());
  }
  return c;
}

/// Per-thread buffers of the locate limits.
struct LocateScratch {
  std::vector<std::int32_t> cells;  ///< one particle's sub-element cells
  std::vector<double> field;        ///< this thread's copy of the field (scatter only)
  std::int64_t index_sum = 0;
};

/// PMM's locate step and nothing else, over every sub-element of the first `count`
/// particles (no fast path, no rotation): the engine's own kernel with the whole grid as
/// the block, so each cell index is floor((centre + r * point - origin) / h) clamped per
/// axis and combined. scatter: then add each sub-element's volume to its cell in this
/// thread's field (never merged: a lower bound), one add per sub-element; otherwise only
/// sum the indices.
template <bool kScatter>
void locate_pass(tbb::task_arena& arena, const BenchScene& s, const vfe::CartesianGridSpec& g,
                 const TemplateChoice& choice, tbb::enumerable_thread_specific<LocateScratch>& scratch,
                 std::int64_t count) {
  const std::size_t ncells = static_cast<std::size_t>(g.cells[0] * g.cells[1] * g.cells[2]);
  const double inv_h = 1.0 / g.spacing[0];  // cubic cells
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, count, 256), [&](const tbb::blocked_range<std::int64_t>& r) {
      LocateScratch& local = scratch.local();
      if (kScatter && local.field.size() != ncells) local.field.assign(ncells, 0.0);
      std::int64_t index_sum = 0;
      for (std::int64_t p = r.begin(); p < r.end(); ++p) {
        const ParticleTemplate& t = choice.templates[choice.of_particle[p]];
        const double* c = s.centres.data() + 3 * p;
        const double radius = s.radii[p];
        const Eigen::Vector3d base((c[0] - g.origin[0]) * inv_h, (c[1] - g.origin[1]) * inv_h,
                                   (c[2] - g.origin[2]) * inv_h);
        const Eigen::Matrix3d to_cells = Eigen::Matrix3d::Identity() * (radius * inv_h);
        const std::size_t n = t.size();
        local.cells.resize(n);
        kernels::locate_in_block(t, base, to_cells, g.cells.data(), local.cells.data());
        const std::int32_t* cell = local.cells.data();
        if constexpr (kScatter) {
          const double volume = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
          double* field = local.field.data();
          for (std::size_t q = 0; q < n; ++q) field[cell[q]] += volume * t.fractions[q];
        } else {
          for (std::size_t q = 0; q < n; ++q) index_sum += cell[q];
        }
      }
      local.index_sum += index_sum;
    });
  });
}

/// Keeps the locate passes' index sums alive (the compiler may not drop the passes).
void sink_index_sums(const std::vector<tbb::enumerable_thread_specific<LocateScratch>>& scratch) {
  for (const auto& per_thread : scratch)
    for (const LocateScratch& local : per_thread) g_sink = double(local.index_sum);
}

/// The machine's control for the methods' speed-ups: the locate limit over the first
/// particles that hold this many sub-elements (a few ms on one thread), timed for every
/// thread count after the engines in each of their rounds. It has no serial part and no
/// shared writes, so its speed-up is what the machine gave two threads at those moments.
constexpr std::int64_t kControlSubElements = 2'000'000;

/// The fewest first particles of `choice` holding `sub_elements` sub-elements (all when the
/// scene has fewer).
std::int64_t control_particles(const TemplateChoice& choice, std::int64_t sub_elements) {
  std::int64_t held = 0, count = 0;
  const auto n = static_cast<std::int64_t>(choice.of_particle.size());
  while (count < n && held < sub_elements)
    held += static_cast<std::int64_t>(choice.templates[choice.of_particle[static_cast<std::size_t>(count++)]].size());
  return count;
}

/// Index in `threads` of the one-thread count, or threads.size() for none.
std::size_t one_thread_index(const std::vector<int>& threads) {
  return static_cast<std::size_t>(std::find(threads.begin(), threads.end(), 1) - threads.begin());
}

/// The speed-up of timings `ms` of `threads` threads over the one-thread timings of the
/// same rounds (round_ratio); NaN for a one-thread timing or without one (null).
RoundRatio speedup_over(const std::vector<double>* one_thread, const std::vector<double>& ms, int threads) {
  if (!one_thread || threads == 1) return {kNaN, kNaN, kNaN};
  return round_ratio(*one_thread, ms);
}

/// The limits of one (scene, grid) for each thread count (an arena each), each the median
/// of `repeats` after a warm-up. A limit's thread counts take turns within each round
/// (time_rounds), and its speed-up is the median of the rounds' ratios to one thread.
std::vector<BenchLimit> measure_limits(std::vector<std::unique_ptr<tbb::task_arena>>& arenas,
                                       const std::vector<int>& threads, const BenchScene& scene,
                                       const vfe::CartesianGridSpec& grid, const TemplateChoice& choice,
                                       std::vector<double>& field, int repeats) {
  const std::size_t nt = arenas.size();
  const std::size_t one = one_thread_index(threads);
  std::vector<BenchLimit> limits(nt);
  auto keep = [&](const std::vector<std::vector<double>>& ms, double BenchLimit::*time, double BenchLimit::*speedup) {
    for (std::size_t k = 0; k < nt; ++k) {
      limits[k].*time = median(ms[k]);
      limits[k].*speedup = speedup_over(one < nt ? &ms[one] : nullptr, ms[k], threads[k]).median;
    }
  };
  double sum = 0;
  for (auto& arena : arenas) sum += bandwidth_pass(*arena, scene, field);
  keep(time_rounds(nt, repeats, [&](std::size_t k) { sum += bandwidth_pass(*arenas[k], scene, field); }),
       &BenchLimit::bandwidth_ms, &BenchLimit::bandwidth_speedup);
  g_sink = sum;
  std::vector<tbb::enumerable_thread_specific<std::vector<double>>> store_fields(nt);
  for (std::size_t k = 0; k < nt; ++k) store_pass(*arenas[k], scene, grid, store_fields[k]);
  keep(time_rounds(nt, repeats, [&](std::size_t k) { store_pass(*arenas[k], scene, grid, store_fields[k]); }),
       &BenchLimit::store_ms, &BenchLimit::store_speedup);
  for (const auto& fields : store_fields)
    for (const std::vector<double>& f : fields) g_sink = f.empty() ? 0.0 : f[0];
  std::vector<tbb::enumerable_thread_specific<LocateScratch>> scratch(nt);
  for (std::size_t k = 0; k < nt; ++k) locate_pass<true>(*arenas[k], scene, grid, choice, scratch[k], scene.n);
  keep(time_rounds(nt, repeats,
                   [&](std::size_t k) { locate_pass<true>(*arenas[k], scene, grid, choice, scratch[k], scene.n); }),
       &BenchLimit::scatter_ms, &BenchLimit::scatter_speedup);
  for (std::size_t k = 0; k < nt; ++k) locate_pass<false>(*arenas[k], scene, grid, choice, scratch[k], scene.n);
  keep(time_rounds(nt, repeats,
                   [&](std::size_t k) { locate_pass<false>(*arenas[k], scene, grid, choice, scratch[k], scene.n); }),
       &BenchLimit::locate_ms, &BenchLimit::locate_speedup);
  sink_index_sums(scratch);
  for (std::size_t k = 0; k < nt; ++k) {
    limits[k].cells = static_cast<std::int64_t>(field.size());
    limits[k].bandwidth_bytes = static_cast<std::int64_t>(sizeof(double)) * (4 * scene.n + limits[k].cells);
    limits[k].threads = threads[k];
    limits[k].locate_sub_elements = choice.sub_elements;
    limits[k].locate_templates = static_cast<std::int64_t>(choice.templates.size());
  }
  return limits;
}

// --- reports ---------------------------------------------------------------------------

using Value = std::variant<std::string, double, std::int64_t>;
struct Field {
  const char* name;
  Value value;
};
using Record = std::vector<Field>;

Record record_of(const BenchRow& r) {
  return {{"scene", r.scene},
          {"dispersity", r.dispersity},
          {"order", r.order},
          {"particles", r.particles},
          {"chi", r.chi},
          {"cell_size", r.cell_size},
          {"nx", r.grid[0]},
          {"ny", r.grid[1]},
          {"nz", r.grid[2]},
          {"cells", r.cells},
          {"solid_fraction", r.solid_fraction},
          {"method", r.method},
          {"options", r.options},
          {"particle_order", r.particle_order},
          {"ordered_blocks", r.ordered_blocks},
          {"threads", std::int64_t{r.threads}},
          {"repeats", std::int64_t{r.repeats}},
          {"time_median_ms", r.time_median_ms},
          {"time_min_ms", r.time_min_ms},
          {"time_max_ms", r.time_max_ms},
          {"particles_per_s", r.particles_per_s},
          {"sub_elements", r.sub_elements},
          {"sub_elements_per_s", r.sub_elements_per_s},
          {"sub_elements_per_particle", r.sub_elements_per_particle},
          {"fast_path_particles", r.fast_path_particles},
          {"particle_grid_min", r.particle_grid_min},
          {"particle_grid_max", r.particle_grid_max},
          {"volume_error", r.volume_error},
          {"engine_bytes", r.engine_bytes},
          {"compute_bytes", r.compute_bytes},
          {"bytes_per_cell", r.bytes_per_cell},
          {"bytes_per_particle", r.bytes_per_particle},
          {"peak_rss_bytes", r.peak_rss_bytes},
          {"speedup", r.speedup},
          {"speedup_min", r.speedup_min},
          {"speedup_max", r.speedup_max},
          {"control_speedup", r.control_speedup},
          {"direct_ratio", r.direct_ratio},
          {"bandwidth_ms", r.bandwidth_ms},
          {"store_ms", r.store_ms},
          {"scatter_ms", r.scatter_ms},
          {"locate_ms", r.locate_ms},
          {"x_bandwidth", r.x_bandwidth},
          {"x_store", r.x_store},
          {"x_scatter", r.x_scatter},
          {"x_locate", r.x_locate}};
}

Record record_of(const BenchLimit& l) {
  const double locate_rate = l.locate_ms > 0 ? double(l.locate_sub_elements) / (l.locate_ms * 1e-3) : kNaN;
  const double bytes_rate = l.bandwidth_ms > 0 ? double(l.bandwidth_bytes) / (l.bandwidth_ms * 1e-3) : kNaN;
  return {{"particles", l.particles},
          {"chi", l.chi},
          {"threads", std::int64_t{l.threads}},
          {"cells", l.cells},
          {"bandwidth_ms", l.bandwidth_ms},
          {"bandwidth_bytes", l.bandwidth_bytes},
          {"bandwidth_bytes_per_s", bytes_rate},
          {"store_ms", l.store_ms},
          {"scatter_ms", l.scatter_ms},
          {"locate_ms", l.locate_ms},
          {"locate_sub_elements", l.locate_sub_elements},
          {"locate_sub_elements_per_s", locate_rate},
          {"locate_templates", l.locate_templates},
          {"bandwidth_speedup", l.bandwidth_speedup},
          {"store_speedup", l.store_speedup},
          {"scatter_speedup", l.scatter_speedup},
          {"locate_speedup", l.locate_speedup}};
}

std::string csv_value(const Value& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return csv_field(*s);
  if (const auto* i = std::get_if<std::int64_t>(&v)) return std::to_string(*i);
  const double x = std::get<double>(v);
  return std::isnan(x) ? "nan" : number_text(x);
}

std::string json_value(const Value& v) {
  if (const auto* s = std::get_if<std::string>(&v)) {
    std::string o = "\"";
    for (char c : *s) {
      if (c == '"' || c == '\\') o += '\\';
      if (static_cast<unsigned char>(c) < 0x20) continue;  // option strings have no control characters
      o += c;
    }
    return o + "\"";
  }
  if (const auto* i = std::get_if<std::int64_t>(&v)) return std::to_string(*i);
  const double x = std::get<double>(v);
  return std::isfinite(x) ? number_text(x) : "null";
}

std::string csv_text(const std::vector<Record>& records) {
  std::string o;
  for (std::size_t i = 0; i < records.size(); ++i) {
    if (i == 0) {
      for (std::size_t c = 0; c < records[0].size(); ++c) o.append(c ? "," : "").append(records[0][c].name);
      o += '\n';
    }
    for (std::size_t c = 0; c < records[i].size(); ++c) o.append(c ? "," : "").append(csv_value(records[i][c].value));
    o += '\n';
  }
  return o;
}

std::string json_array(const std::vector<Record>& records) {
  std::string o = "[";
  for (std::size_t i = 0; i < records.size(); ++i) {
    o += i ? ",\n    {" : "\n    {";
    for (std::size_t c = 0; c < records[i].size(); ++c)
      o.append(c ? ", \"" : "\"").append(records[i][c].name).append("\": ").append(json_value(records[i][c].value));
    o += "}";
  }
  return o + (records.empty() ? "]" : "\n  ]");
}

// --- the table ---------------------------------------------------------------------------

std::string cell_text(const char* format, double v) {
  if (!std::isfinite(v)) return "-";
  char buf[40];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

constexpr const char* kRowFormat = "%8s %4s %-14s %3s %9s %10s %8s %8s %7s %7s %6s %7s %5s %6s %7s %7s %9s %8s\n";

void print_header(std::ostream& out) {
  char line[256];
  std::snprintf(line, sizeof line, kRowFormat, "N", "chi", "method", "thr", "cells", "ms", "part/s", "subel/s",
                "subel/p", "B/part", "B/cell", "speedup", "ctl", "x dir", "x bw", "x store", "x scatter", "x locate");
  out << line << std::string(std::char_traits<char>::length(line) - 1, '-') << '\n';
}

void print_line(std::ostream& out, std::int64_t n, double chi, const std::string& method, int threads,
                std::int64_t cells, double ms, double sub_elements, double bytes_per_particle, double bytes_per_cell,
                double speedup, double control_speedup, double direct_ratio, double x_bandwidth, double x_store,
                double x_scatter, double x_locate) {
  const double per_s = 1e3 / ms;
  char line[256];
  std::snprintf(line, sizeof line, kRowFormat, std::to_string(n).c_str(), cell_text("%.3g", chi).c_str(),
                method.c_str(), std::to_string(threads).c_str(), std::to_string(cells).c_str(),
                cell_text("%.3f", ms).c_str(), cell_text("%.3g", double(n) * per_s).c_str(),
                cell_text("%.3g", sub_elements * per_s).c_str(), cell_text("%.4g", sub_elements / double(n)).c_str(),
                cell_text("%.1f", bytes_per_particle).c_str(), cell_text("%.1f", bytes_per_cell).c_str(),
                cell_text("%.2f", speedup).c_str(), cell_text("%.2f", control_speedup).c_str(),
                cell_text("%.2f", direct_ratio).c_str(), cell_text("%.1f", x_bandwidth).c_str(),
                cell_text("%.2f", x_store).c_str(), cell_text("%.2f", x_scatter).c_str(), cell_text("%.2f", x_locate).c_str());
  out << line << std::flush;
}

}  // namespace

void sort_morton(BenchScene& s) {
  // Spread 21 bits so that two zero bits follow each: x's bits land at 0, 3, 6, ...
  auto spread = [](std::uint64_t v) {
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffull;
    v = (v | v << 16) & 0x1f0000ff0000ffull;
    v = (v | v << 8) & 0x100f00f00f00f00full;
    v = (v | v << 4) & 0x10c30c30c30c30c3ull;
    v = (v | v << 2) & 0x1249249249249249ull;
    return v;
  };
  std::vector<std::pair<std::uint64_t, std::int64_t>> keys(static_cast<std::size_t>(s.n));
  for (std::int64_t p = 0; p < s.n; ++p) {
    std::uint64_t key = 0;
    for (int d = 0; d < 3; ++d) {
      const double t = (s.centres[3 * p + d] - s.lo[d]) / std::max(s.hi[d] - s.lo[d], 1e-300);
      key |= spread(static_cast<std::uint64_t>(std::clamp(t, 0.0, 1.0) * double(0x1fffff))) << d;
    }
    keys[p] = {key, p};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<double> centres(s.centres.size()), radii(s.radii.size());
  for (std::int64_t q = 0; q < s.n; ++q) {
    const std::int64_t p = keys[q].second;
    for (int d = 0; d < 3; ++d) centres[3 * q + d] = s.centres[3 * p + d];
    radii[q] = s.radii[p];
  }
  s.centres.swap(centres);
  s.radii.swap(radii);
}

BenchScene make_bench_scene(const std::string& scene, const std::string& dispersity, std::int64_t n,
                            std::uint64_t seed) {
  check_scene_kind(scene, dispersity);
  if (n < 1) bad_argument("--particles: " + std::to_string(n) + " particles; expected a count >= 1");
  SplitMix64 rng(seed);
  BenchScene s;
  s.name = scene;
  s.dispersity = dispersity;
  s.n = n;
  s.radii.resize(static_cast<std::size_t>(n));
  s.centres.resize(static_cast<std::size_t>(3 * n));
  double sum_d = 0;
  for (auto& r : s.radii) {
    const double d = dispersity == "poly" ? 1.0 - kPolySpread + 2 * kPolySpread * rng.uniform() : 1.0;
    r = 0.5 * d;
    sum_d += d;
    s.particle_volume += std::numbers::pi / 6 * d * d * d;
  }
  s.mean_diameter = sum_d / double(n);
  const double mean_volume = s.particle_volume / double(n);

  if (scene == "bed") {
    // Face-centred cubic: the sites (u, v, l) * a/2 with u + v + l even, 4 per cube of side
    // a, sized for the target fraction; L x L cubes wide (a roughly cubic bed), filled
    // layer by layer from the bottom, the top layer's sites picked at random.
    const double a = std::cbrt(4 * mean_volume / kBedFraction);
    const auto L = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(std::cbrt(double(n) / 4))));
    const std::int64_t per_layer = 2 * L * L;
    const double jitter = 0.25 * std::max(0.0, a / std::numbers::sqrt2 - s.mean_diameter);
    std::vector<std::int64_t> sites(static_cast<std::size_t>(per_layer));
    std::int64_t p = 0;
    for (std::int64_t l = 0; p < n; ++l) {
      std::size_t count = 0;
      for (std::int64_t v = 0; v < 2 * L; ++v)
        for (std::int64_t u = 0; u < 2 * L; ++u)
          if ((u + v + l) % 2 == 0) sites[count++] = u + 2 * L * v;
      const std::int64_t take = std::min(per_layer, n - p);
      for (std::int64_t i = 0; i < take && take < per_layer; ++i)
        std::swap(sites[i], sites[i + static_cast<std::int64_t>(rng.below(std::uint64_t(per_layer - i)))]);
      for (std::int64_t i = 0; i < take; ++i, ++p) {
        const double site[3] = {double(sites[i] % (2 * L)), double(sites[i] / (2 * L)), double(l)};
        for (int d = 0; d < 3; ++d)
          s.centres[3 * p + d] = (site[d] + 0.5) * 0.5 * a + jitter * (2 * rng.uniform() - 1);
      }
    }
    s.hi = {double(L) * a, double(L) * a, double(n) / double(per_layer) * 0.5 * a};
  } else {
    const double side = std::cbrt(s.particle_volume / kStreamFraction);
    for (std::int64_t p = 0; p < n; ++p) {
      const double r = s.radii[p];
      for (int d = 0; d < 3; ++d) s.centres[3 * p + d] = r + (side - 2 * r) * rng.uniform();
    }
    s.hi = {side, side, side};
  }
  s.solid_fraction = s.particle_volume / ((s.hi[0] - s.lo[0]) * (s.hi[1] - s.lo[1]) * (s.hi[2] - s.lo[2]));

  // Shuffled: a generator's order (layer by layer) would give the engine an unrealistic
  // memory locality.
  for (std::int64_t i = n - 1; i > 0; --i) {
    const auto j = static_cast<std::int64_t>(rng.below(std::uint64_t(i + 1)));
    std::swap(s.radii[i], s.radii[j]);
    for (int d = 0; d < 3; ++d) std::swap(s.centres[3 * i + d], s.centres[3 * j + d]);
  }
  return s;
}

BenchOutcome run_bench(const BenchCommand& c) {
  const auto quiet_sink = std::make_shared<spdlog::sinks::null_sink_mt>();
  const auto log = c.logger ? c.logger : std::make_shared<spdlog::logger>("vfe-app", quiet_sink);
  share_one_malloc_arena();
  // Every argument is checked before the first (possibly long) scene is made.
  check_scene_kind(c.scene, c.dispersity);
  if (c.order != "shuffled" && c.order != "morton")
    bad_argument("--order: unknown order '" + c.order + "'; expected shuffled or morton");
  const std::vector<std::int64_t> counts = particle_counts(c.particles);
  if (c.chi.empty()) bad_argument("--chi: no value; give cell size / mean diameter such as 1,2");
  for (double x : c.chi)
    if (!(x > 0) || !std::isfinite(x)) bad_argument("--chi: bad value '" + number_text(x) + "'; expected numbers > 0");
  if (c.threads.empty()) bad_argument("--threads: no value; give thread counts such as 1,2");
  std::vector<int> threads;
  for (int t : c.threads) {
    if (t < 0 || t > 4096) bad_argument("--threads: bad value '" + std::to_string(t) + "'; expected 0 (all) to 4096");
    const unsigned hc = std::thread::hardware_concurrency();
    threads.push_back(t > 0 ? t : (hc ? static_cast<int>(hc) : 1));
  }
  if (c.methods.empty()) bad_argument("--method: no value; give methods such as direct,pmm,exact (or all)");
  // "all": every method the engine has, in its order.
  std::vector<std::string> methods = c.methods;
  if (methods == std::vector<std::string>{"all"}) methods = engine_method_names();
  if (c.repeats < 1) bad_argument("--repeats: bad value '" + std::to_string(c.repeats) + "'; expected a count >= 1");
  check_free_options(c.options, !c.particle_orders.empty());

  const std::string common = c.options + " particle_grid=" + c.particle_grid;
  vfe::Engine probe(vfe::CartesianGridSpec{});
  configure_or_throw(probe, c.options, "--options");
  configure_or_throw(probe, "particle_grid=" + c.particle_grid, "--particle-grid");
  for (const std::string& m : methods) configure_or_throw(probe, "method=" + m, "--method");
  // The engine's default when not given; several are timed alternately, one engine each.
  const std::vector<std::string> orders = c.particle_orders.empty() ? std::vector<std::string>{""} : c.particle_orders;
  for (const std::string& o : orders)
    if (!o.empty()) configure_or_throw(probe, "particle_order=" + o, "--particle-order");
  probe.configure("method=pmm");  // the limits use pmm's template sizes

  std::error_code ec;
  fs::create_directories(c.output, ec);
  if (ec || !fs::is_directory(c.output))
    throw std::runtime_error(c.output.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output");

  BenchOutcome out;
  out.output = c.output;
  if (c.table) print_header(*c.table);
  const std::size_t total_rows = counts.size() * c.chi.size() * threads.size() * methods.size() * orders.size();
  for (const std::int64_t n : counts) {
    const auto t_scene = Clock::now();
    BenchScene scene = make_bench_scene(c.scene, c.dispersity, n, c.seed);
    if (c.order == "morton") sort_morton(scene);
    log->info("{} ({}): {} particles, solid fraction {:.3f}, mean diameter {:.4g}, made in {:.2f} s", scene.name,
              scene.dispersity, n, scene.solid_fraction, scene.mean_diameter, ms_since(t_scene) * 1e-3);
    vfe::ParticleView view;
    view.n = n;
    view.centres = scene.centres.data();
    view.radii = scene.radii.data();

    for (const double chi : c.chi) {
      // Cubic cells of chi mean diameters over the scene's box and a margin of one diameter.
      const double h = chi * scene.mean_diameter, margin = scene.mean_diameter;
      vfe::CartesianGridSpec grid;
      double cell_estimate = 1;
      for (int d = 0; d < 3; ++d) {
        const double cells = std::ceil((scene.hi[d] - scene.lo[d] + 2 * margin) / h);
        cell_estimate *= cells;
        grid.origin[d] = scene.lo[d] - margin;
        grid.spacing[d] = h;
        grid.cells[d] = static_cast<std::int64_t>(std::min(cells, kMaxCells));
      }
      if (cell_estimate > kMaxCells)
        bad_argument("--chi: chi = " + number_text(chi) + " with " + std::to_string(n) + " particles needs " +
                     number_text(cell_estimate) + " cells; use a larger chi or fewer particles");
      const std::int64_t ncells = grid.cells[0] * grid.cells[1] * grid.cells[2];
      log->info("N = {}, chi = {}: {} x {} x {} cells", n, chi, grid.cells[0], grid.cells[1], grid.cells[2]);
      const TemplateChoice choice = c.limits ? choose_templates(probe, scene, h) : TemplateChoice{};
      std::vector<double> field(static_cast<std::size_t>(ncells), 0.0);  // the host's output, touched

      // Every thread count's limits and engines are timed in turn within each round, so that
      // the speed-ups are ratios of times taken moments apart.
      std::vector<std::unique_ptr<tbb::task_arena>> arenas;
      for (const int t : threads) arenas.push_back(std::make_unique<tbb::task_arena>(t));
      const std::size_t one = one_thread_index(threads);
      // The control pass of each thread count (none without limits or a one-thread count).
      const bool control = c.limits && one < threads.size();
      std::vector<tbb::enumerable_thread_specific<LocateScratch>> control_scratch(control ? threads.size() : 0);
      const std::int64_t control_count = control ? control_particles(choice, kControlSubElements) : 0;
      const auto control_pass = [&](std::size_t k) {
        locate_pass<false>(*arenas[k], scene, grid, choice, control_scratch[k], control_count);
      };
      for (std::size_t k = 0; k < control_scratch.size(); ++k) control_pass(k);
      std::vector<BenchLimit> limits(threads.size());
      for (std::size_t k = 0; k < threads.size(); ++k) {
        BenchLimit& limit = limits[k];
        limit.threads = threads[k];
        limit.bandwidth_ms = limit.store_ms = limit.scatter_ms = limit.locate_ms = kNaN;
      }
      if (c.limits) {
        limits = measure_limits(arenas, threads, scene, grid, choice, field, c.repeats);
        for (BenchLimit& limit : limits) {
          limit.particles = n;
          limit.chi = chi;
          out.limits.push_back(limit);
          log->info("limits, {} thread(s): bandwidth {:.3f} ms, store {:.3f} ms, scatter {:.3f} ms, locate {:.3f} ms "
                    "({} template sizes)",
                    limit.threads, limit.bandwidth_ms, limit.store_ms, limit.scatter_ms, limit.locate_ms,
                    limit.locate_templates);
          if (c.table) {
            const int t = limit.threads;
            const double subel = double(limit.locate_sub_elements);
            print_line(*c.table, n, chi, "(bw)", t, ncells, limit.bandwidth_ms, kNaN, kNaN, kNaN,
                       limit.bandwidth_speedup, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN);
            print_line(*c.table, n, chi, "(store)", t, ncells, limit.store_ms, double(n), kNaN, kNaN,
                       limit.store_speedup, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN);
            print_line(*c.table, n, chi, "(scatter)", t, ncells, limit.scatter_ms, subel, kNaN, kNaN,
                       limit.scatter_speedup, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN);
            print_line(*c.table, n, chi, "(locate)", t, ncells, limit.locate_ms, subel, kNaN, kNaN,
                       limit.locate_speedup, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN);
          }
        }
      }

      // One engine per method, thread count and particle order, each created and warmed up in
      // turn (its memory measured alone), then timed in rounds that take every engine once
      // and the control of each thread count after them: a method's ratio to direct and its
      // speed-up are ratios of times taken moments apart.
      struct Timed {
        std::unique_ptr<vfe::Engine> engine;
        std::int64_t before_engine = -1, after_engine = -1, before_compute = -1, after_compute = -1;
        vfe::Report rep{};
      };
      const std::size_t norders = orders.size(), per_method = threads.size() * norders;
      std::vector<Timed> timed(methods.size() * per_method);  // [method][thread count][order]
      for (std::size_t i = 0; i < timed.size(); ++i) {
        Timed& e = timed[i];
        const std::string& method = methods[i / per_method];
        const int t = threads[i % per_method / norders];
        const std::string& order = orders[i % norders];
        return_free_memory();
        e.before_engine = resident_bytes();
        e.engine = std::make_unique<vfe::Engine>(grid);
        e.after_engine = resident_bytes();
        e.engine->configure(common + " method=" + method + " threads=" + std::to_string(t) +
                            (order.empty() ? "" : " particle_order=" + order));
        return_free_memory();
        e.before_compute = resident_bytes();
        const auto t_warm = Clock::now();
        e.engine->compute(view, field);
        const double warm_ms = ms_since(t_warm);
        e.after_compute = resident_bytes();
        if (warm_ms > 5000)
          log->info("{}, {} thread(s): warm-up took {:.1f} s; {} timed computes follow", method, t, warm_ms * 1e-3,
                    c.repeats);
        e.rep = e.engine->last_report();
        warn_overfull(*log, scene.name + " chi=" + printf_number("%.3g", chi), method, overfull_facts(*e.engine),
                      e.rep.particle_volume);
      }
      // The engines, then the control of each thread count, in every round.
      int round = 0;
      const std::vector<std::vector<double>> ms =
          time_rounds(timed.size() + control_scratch.size(), c.repeats, [&](std::size_t i) {
            if (i == 0) log->info("N = {}, chi = {}: round {} of {}", n, chi, ++round, c.repeats);
            if (i < timed.size())
              timed[i].engine->compute(view, field);
            else
              control_pass(i - timed.size());
          });
      // direct's engines in the rounds, per thread count and order: the base of the ratios to direct.
      const auto direct_at = std::find(methods.begin(), methods.end(), "direct");
      const std::size_t direct_first =
          direct_at == methods.end() ? timed.size() : std::size_t(direct_at - methods.begin()) * per_method;
      for (std::size_t i = 0; i < timed.size(); ++i) {
        const std::string& method = methods[i / per_method];
        const std::size_t k = i % per_method / norders;
        const int t = threads[k];
        const BenchLimit& limit = limits[k];
        BenchRow row;
        const vfe::Engine& engine = *timed[i].engine;
        const vfe::Report& rep = timed[i].rep;
        const std::int64_t before_engine = timed[i].before_engine, after_engine = timed[i].after_engine;
        const std::int64_t before_compute = timed[i].before_compute, after_compute = timed[i].after_compute;
        const double median_ms = median(ms[i]);
        const auto [fastest, slowest] = std::minmax_element(ms[i].begin(), ms[i].end());
        const std::string label = norders > 1 ? method + "/" + orders[i % norders] : method;
        row.particle_order = engine.option("particle_order");
        row.ordered_blocks = std::int64_t(engine.last_report_value("ordered_blocks"));
        const bool have_memory = before_engine >= 0 && before_compute >= 0;
        row.scene = scene.name;
        row.order = c.order;
        row.dispersity = scene.dispersity;
        row.method = method;
        row.options = engine.options();
        row.particles = n;
        row.chi = chi;
        row.cell_size = h;
        row.solid_fraction = scene.solid_fraction;
        row.grid = grid.cells;
        row.cells = ncells;
        row.threads = t;
        row.repeats = c.repeats;
        row.time_median_ms = median_ms;
        row.time_min_ms = *fastest;
        row.time_max_ms = *slowest;
        row.particles_per_s = double(n) / (median_ms * 1e-3);
        row.sub_elements = rep.sub_elements;
        row.sub_elements_per_s = double(rep.sub_elements) / (median_ms * 1e-3);
        row.sub_elements_per_particle = double(rep.sub_elements) / double(n);
        row.fast_path_particles = rep.fast_path_particles;
        row.particle_grid_min = rep.particle_grid_min;
        row.particle_grid_max = rep.particle_grid_max;
        row.volume_error = std::abs(rep.deposited_volume + rep.dropped_volume - rep.particle_volume) /
                           rep.particle_volume;
        row.engine_bytes = have_memory ? after_engine - before_engine : -1;
        row.compute_bytes = have_memory ? after_compute - before_compute : -1;
        row.bytes_per_cell = have_memory ? double(row.engine_bytes) / double(ncells) : kNaN;
        row.bytes_per_particle = have_memory ? double(row.compute_bytes) / double(n) : kNaN;
        row.peak_rss_bytes = peak_resident_bytes();
        const std::size_t method_first = i - i % per_method;
        const RoundRatio speedup =
            speedup_over(one < threads.size() ? &ms[method_first + one * norders + i % norders] : nullptr, ms[i], t);
        row.speedup = speedup.median;
        row.speedup_min = speedup.min;
        row.speedup_max = speedup.max;
        row.control_speedup = control ? speedup_over(&ms[timed.size() + one], ms[timed.size() + k], t).median : kNaN;
        row.direct_ratio =
            direct_first < timed.size() ? round_ratio(ms[i], ms[direct_first + i % per_method]).median : kNaN;
        row.bandwidth_ms = limit.bandwidth_ms;
        row.store_ms = limit.store_ms;
        row.scatter_ms = limit.scatter_ms;
        row.locate_ms = limit.locate_ms;
        row.x_bandwidth = row.time_median_ms / limit.bandwidth_ms;
        row.x_store = row.time_median_ms / limit.store_ms;
        row.x_scatter = row.time_median_ms / limit.scatter_ms;
        row.x_locate = row.time_median_ms / limit.locate_ms;
        out.rows.push_back(row);
        log->info("[{}/{}] N = {}, chi = {}, {}, {} thread(s): {:.3f} ms per compute", out.rows.size(), total_rows,
                  n, chi, label, t, row.time_median_ms);
        if (c.table)
          print_line(*c.table, n, chi, label, t, ncells, row.time_median_ms, double(row.sub_elements),
                     row.bytes_per_particle, row.bytes_per_cell, row.speedup, row.control_speedup, row.direct_ratio,
                     row.x_bandwidth, row.x_store, row.x_scatter, row.x_locate);
      }
      sink_index_sums(control_scratch);
    }
  }
  out.peak_rss_bytes = peak_resident_bytes();
  if (c.table)
    *c.table << "(bw: read centres and radii, clear the field; store: add each volume to its centre's cell; scatter: pmm's cell index of every sub-element and "
                "an add there; locate: the index only; ctl: the speed-up of a short locate pass timed in the same rounds, "
                "what the machine gave; x dir: time / direct's in the same round, the median over the rounds; "
                "x ...: time / that limit; B/part: RSS growth over the first "
                "compute / N; B/cell: RSS growth on creating the engine / cells)\npeak RSS: "
             << cell_text("%.1f", double(out.peak_rss_bytes) / (1 << 20)) << " MiB\n"
             << std::flush;

  std::vector<Record> rows, limits;
  for (const BenchRow& r : out.rows) rows.push_back(record_of(r));
  for (const BenchLimit& l : out.limits) limits.push_back(record_of(l));
  write_text_file(c.output / "bench.csv", csv_text(rows));
  write_text_file(c.output / "limits.csv", csv_text(limits));
  std::ostringstream js;
  const Record info = {{"vfe_version", std::string(vfe_version())},
                       {"scene", c.scene},
                       {"dispersity", c.dispersity},
                       {"seed", static_cast<std::int64_t>(c.seed)},
                       {"repeats", std::int64_t{c.repeats}},
                       {"particle_grid", c.particle_grid},
                       {"options", c.options},
                       {"hardware_threads", std::int64_t{std::thread::hardware_concurrency()}},
                       {"peak_rss_bytes", out.peak_rss_bytes}};
  js << "{\n";
  for (const Field& f : info) js << "  \"" << f.name << "\": " << json_value(f.value) << ",\n";
  js << "  \"rows\": " << json_array(rows) << ",\n  \"limits\": " << json_array(limits) << "\n}\n";
  write_text_file(c.output / "bench.json", js.str());
  log->info("wrote {}, {} and {}", (c.output / "bench.csv").string(), (c.output / "limits.csv").string(),
            (c.output / "bench.json").string());
  return out;
}

CliCommand register_bench(CLI::App& app) {
  struct Args {
    BenchCommand bench_cmd;
    bool bench_quiet = false;
  };
  const auto args = std::make_shared<Args>();
  CLI::App* bench = app.add_subcommand(
      "bench", "Throughput of the methods on generated scenes (packed bed or dilute stream): time, sub-elements/s, "
               "memory, thread speed-up and measured limits (bench.csv, limits.csv, bench.json)");
  bench->add_option("--scene", args->bench_cmd.scene, "bed (packed, solid fraction 0.58) or stream (dilute, 0.05)")
      ->capture_default_str();
  bench->add_option("--dispersity", args->bench_cmd.dispersity, "mono (diameter 1) or poly (uniform in [0.7, 1.3])")
      ->capture_default_str();
  bench->add_option("--order", args->bench_cmd.order,
                    "The particles' order: shuffled (as after a DEM code's neighbour-list rebuild) or morton (sorted "
                    "along a Z-order curve)")
      ->capture_default_str();
  bench->add_option("-n,--particles", args->bench_cmd.particles,
                    "Particle counts, a list (default 1e4,1e5; e.g. 1e4,1e5,1e6,4e6)")
      ->delimiter(',');
  bench->add_option("--chi", args->bench_cmd.chi, "Cell size / mean diameter, a list (default 2; e.g. 0.5,1,2,4)")
      ->delimiter(',');
  bench->add_option("-t,--threads", args->bench_cmd.threads,
                    "Thread counts, a list (default 1,2; 0 = all): one engine each, timed in turn; a speed-up is the "
                    "median of the ratios within a round")
      ->delimiter(',');
  bench->add_option("--method", args->bench_cmd.methods, "Engine methods, a list (default direct,pmm,exact), or all")->delimiter(',');
  bench->add_option("--particle-grid", args->bench_cmd.particle_grid, "pmm's particle_grid: auto or a count")
      ->capture_default_str();
  bench->add_option("--particle-order", args->bench_cmd.particle_orders,
                    "The engine's particle_order, a list (e.g. input,blocked): one engine each, timed alternately "
                    "(default: the engine's default, auto)")
      ->delimiter(',');
  bench->add_option("--options", args->bench_cmd.options, "More engine options, \"key=value ...\" (e.g. orientation=none)");
  bench->add_option("-r,--repeats", args->bench_cmd.repeats, "Timed computes after one warm-up (the median is reported)")
      ->capture_default_str();
  bench->add_option("--seed", args->bench_cmd.seed, "Seed of the generated scene")->capture_default_str();
  bench->add_flag("!--no-limits", args->bench_cmd.limits, "Skip the bandwidth and locate limits (e.g. to profile a method)");
  bench->add_option("-o,--output", args->bench_cmd.output, "Output folder")->capture_default_str();
  bench->add_flag("-q,--quiet", args->bench_quiet, "Print only the table, warnings and errors");

  return {bench, [args] {
    args->bench_cmd.logger = make_app_logger(args->bench_quiet);
    args->bench_cmd.table = &std::cout;
    run_bench(args->bench_cmd);
    return 0;
  }};
}

}  // namespace vfe::apps

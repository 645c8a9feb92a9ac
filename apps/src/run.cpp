#include "run.hpp"

#include "dump_reader.hpp"
#include "vtk_writer.hpp"

#include <vfe/engine.hpp>
#include <vfe/measures.hpp>

#include <spdlog/logger.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <thread>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

std::string g3(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

/// Runs f; an engine Error gets the mesh and method it happened in.
template <class F>
void with_context(const std::string& where, F&& f) {
  try {
    f();
  } catch (const vfe::Error& e) {
    throw vfe::Error(e.status(), where + ": " + e.what());
  }
}

int resolve_threads(const std::string& value) {
  int t = 0;
  try {
    t = std::stoi(value);
  } catch (...) {
    t = 0;
  }
  if (t > 0) return t;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc ? static_cast<int>(hc) : 1;
}

}  // namespace

std::shared_ptr<spdlog::logger> make_app_logger(bool quiet) {
  auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  auto logger = std::make_shared<spdlog::logger>("vfe-app", std::move(sink));
  logger->set_pattern("[%T] %^%l%$: %v");
  logger->set_level(quiet ? spdlog::level::warn : spdlog::level::info);
  return logger;
}

RunResult run_scene(const SceneConfig& cfg, const RunOptions& opt) {
  const auto log = opt.logger ? opt.logger : make_app_logger(true);
  const std::string source = cfg.source.string();
  const int repeats = opt.repeats.value_or(cfg.repeats);
  if (repeats < 1) throw ConfigError(source + ": repeats must be >= 1 (got " + std::to_string(repeats) + ")");
  if (opt.threads && *opt.threads < 0)
    throw ConfigError("threads must be 0 (all) or a count >= 1 (got " + std::to_string(*opt.threads) + ")");
  const bool vtk = opt.vtk || cfg.vtk;
  const fs::path out_dir = opt.output.value_or(cfg.output);

  // Options for every method: config threads, then the config's options, then --threads.
  std::vector<std::string> global_parts = {"threads=" + std::to_string(cfg.threads), cfg.options};
  if (opt.threads) global_parts.push_back("threads=" + std::to_string(*opt.threads));
  std::string global;
  try {
    global = merge_options(global_parts);
  } catch (const ConfigError& e) {
    throw ConfigError(source + ": options: " + e.what());
  }

  // The methods to time (one per setting), and the reference (timed too when it is one of them).
  std::vector<MethodSpec> methods = expand_settings(cfg.methods);
  const MethodSpec reference = cfg.reference;
  const bool reference_listed = std::any_of(methods.begin(), methods.end(), [&](const MethodSpec& m) {
    return m.label == reference.label && m.method == reference.method && m.options == reference.options;
  });

  // Check every option string on a one-cell engine before reading the particles, so a
  // typo fails at once. Each method starts from the engine's defaults, so one method's
  // options never leak into the next.
  std::string defaults;
  int threads_used = 0;
  {
    vfe::Engine probe(vfe::CartesianGridSpec{});
    defaults = probe.options();
    auto check = [&](const MethodSpec& m, const std::string& what) {
      try {
        probe.configure(merge_options({defaults, global, "method=" + m.method, m.options}));
      } catch (const vfe::Error& e) {
        throw ConfigError(source + ": " + what + " '" + m.label + "': " + e.what());
      } catch (const ConfigError& e) {
        throw ConfigError(source + ": " + what + " '" + m.label + "': " + e.what());
      }
    };
    check(reference, "reference");
    for (const auto& m : methods) check(m, "method");
    probe.configure(merge_options({defaults, global}));
    threads_used = resolve_threads(probe.option("threads"));
  }
  auto engine_options = [&](const MethodSpec& m) {
    return merge_options({defaults, global, "method=" + m.method, m.options});
  };

  // Particles.
  log->info("reading {}", cfg.particles_file.string());
  auto t0 = Clock::now();
  const DumpFrame frame = read_dump_frame(cfg.particles_file.string(), FrameSelector{cfg.frame});
  const double mean_d = frame.mean_diameter();
  log->info("{} particles at timestep {} (mean diameter {}), read in {:.0f} ms", frame.n, frame.timestep,
            g3(mean_d), ms_since(t0));
  const vfe::ParticleView particles = frame.view();

  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir))
    throw std::runtime_error(out_dir.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output or 'output:'");

  RunInfo info;
  info.scene = cfg.name;
  info.particles_file = cfg.particles_file.filename().string();
  info.timestep = frame.timestep;
  info.particles = frame.n;
  info.particle_volume = frame.total_volume();
  info.mean_diameter = mean_d;
  info.reference = reference.label;
  info.threads = threads_used;
  info.repeats = repeats;
  info.options = global;
  info.version = vfe_version();

  RunResult result;
  result.output = out_dir;

  std::vector<MeshSpec> meshes = cfg.meshes;
  if (!cfg.chi.empty() && !(mean_d > 0))
    throw ConfigError(source + ": chi: [...] needs particles to size the cells (the frame has none); list meshes "
                               "instead");
  for (double chi : cfg.chi) meshes.push_back(chi_mesh(chi, mean_d));

  for (std::size_t mesh_index = 0; mesh_index < meshes.size(); ++mesh_index) {
    const MeshSpec& mesh = meshes[mesh_index];
    std::string note;
    const vfe::CartesianGridSpec grid = resolve_grid(mesh, &frame.box, source, &note);
    // A chi mesh keeps its spacing exactly, so extending past the box is expected there.
    if (!note.empty()) {
      if (mesh_index < cfg.meshes.size())
        log->warn("mesh '{}': {}", mesh.name, note);
      else
        log->info("mesh '{}': {}", mesh.name, note);
    }
    const std::string mesh_where = "mesh '" + mesh.name + "'";
    std::unique_ptr<vfe::Engine> engine;
    with_context(mesh_where, [&] { engine = std::make_unique<vfe::Engine>(grid); });
    const auto ncells = static_cast<std::size_t>(engine->cell_count());
    std::vector<double> cell_volume(ncells), ref(ncells), solid(ncells), eps(ncells);
    engine->cell_volumes(cell_volume);
    double mean_cell_volume = 0;
    for (double v : cell_volume) mean_cell_volume += v;
    mean_cell_volume /= static_cast<double>(std::max<std::size_t>(ncells, 1));
    const double cell_size = std::cbrt(mean_cell_volume);
    const double chi = mean_d > 0 ? cell_size / mean_d : 0.0;
    log->info("mesh '{}': {} x {} x {} cells of {} (chi = {:.2f})", mesh.name, grid.cells[0], grid.cells[1],
              grid.cells[2], g3(cell_size), chi);

    std::vector<CellArray> vtk_arrays;

    // Reference, once.
    double particle_volume = 0;
    with_context(mesh_where + ", reference '" + reference.label + "'", [&] {
      engine->configure(engine_options(reference));
      t0 = Clock::now();
      engine->compute(particles, ref);
      log->info("  reference {}: {:.3f} ms", reference.label, ms_since(t0));
      particle_volume = engine->last_report().particle_volume;
      if (vtk && !reference_listed) {
        engine->void_fraction(eps);
        vtk_arrays.push_back({"voidfraction_" + reference.label, eps});
        vtk_arrays.push_back({"solid_volume_" + reference.label, ref});
      }
    });

    std::vector<ResultRow> mesh_rows;
    for (const auto& m : methods) {
      ResultRow row;
      const std::string opts = engine_options(m);
      with_context(mesh_where + ", method '" + m.label + "'", [&] {
        engine->configure(opts);
        engine->compute(particles, solid);  // warm-up
        std::vector<double> times;
        times.reserve(static_cast<std::size_t>(repeats));
        for (int r = 0; r < repeats; ++r) {
          const auto t = Clock::now();
          engine->compute(particles, solid);
          times.push_back(ms_since(t));
        }
        // The void fraction (untimed) also sets the report's clipped volume.
        engine->void_fraction(eps);
        const vfe::Report rep = engine->last_report();
        row.mesh = mesh.name;
        row.label = m.label;
        row.method = m.method;
        row.options = opts;
        row.is_reference = m.label == reference.label;
        row.grid = grid.cells;
        row.cells = static_cast<std::int64_t>(ncells);
        row.cell_size = cell_size;
        row.chi = chi;
        row.particles = frame.n;
        row.threads = threads_used;
        row.repeats = repeats;
        row.time_median_ms = median(times);
        row.time_min_ms = *std::min_element(times.begin(), times.end());
        const double sec = row.time_median_ms * 1e-3;
        row.particles_per_s = sec > 0 ? static_cast<double>(frame.n) / sec : 0.0;
        row.sub_elements_per_s = sec > 0 ? static_cast<double>(rep.sub_elements) / sec : 0.0;
        row.sub_elements = rep.sub_elements;
        row.fast_path_particles = rep.fast_path_particles;
        row.particle_grid_min = rep.particle_grid_min;
        row.particle_grid_max = rep.particle_grid_max;
        row.accuracy = vfe::compare_fields(solid, ref, cell_volume, particle_volume);
        row.particle_volume = rep.particle_volume;
        row.deposited_volume = rep.deposited_volume;
        row.dropped_volume = rep.dropped_volume;
        row.clipped_volume = rep.clipped_volume;
        row.outside_particles = rep.outside_particles;
        log->info("  {}: {:.3f} ms per compute (median of {}), theta {:.3e}", m.label, row.time_median_ms,
                  repeats, row.accuracy.theta);
        if (rep.dropped_volume > 0)
          log->warn("  {}: {} particle(s) lie partly outside mesh '{}'; outside={} dropped {} of their volume "
                    "({:.3e} of the particle volume)",
                    m.label, rep.outside_particles, mesh.name, engine->option("outside"), g3(rep.dropped_volume),
                    rep.particle_volume > 0 ? rep.dropped_volume / rep.particle_volume : 0.0);
        else if (rep.outside_particles > 0)
          log->info("  {}: {} particle(s) lie partly outside mesh '{}' (outside={})", m.label,
                    rep.outside_particles, mesh.name, engine->option("outside"));
        if (rep.clipped_volume > 0)
          log->info("  {}: the void fraction was clipped at alpha_min={} in some cells ({} of solid volume)",
                    m.label, engine->option("alpha_min"), g3(rep.clipped_volume));
        if (vtk) {
          vtk_arrays.push_back({"voidfraction_" + m.label, eps});
          vtk_arrays.push_back({"solid_volume_" + m.label, solid});
        }
      });
      mesh_rows.push_back(std::move(row));
    }

    if (opt.table) {
      char title[512];
      std::snprintf(title, sizeof title,
                    "\n%s / mesh %s: %lld x %lld x %lld cells of %s (chi = %.2f), %lld particles, %d thread(s), "
                    "median of %d, reference %s",
                    cfg.name.c_str(), mesh.name.c_str(), static_cast<long long>(grid.cells[0]),
                    static_cast<long long>(grid.cells[1]), static_cast<long long>(grid.cells[2]),
                    g3(cell_size).c_str(), chi, static_cast<long long>(frame.n), threads_used, repeats,
                    reference.label.c_str());
      print_table(*opt.table, title, mesh_rows);
    }
    result.rows.insert(result.rows.end(), mesh_rows.begin(), mesh_rows.end());

    if (vtk) {
      const fs::path f = out_dir / (mesh.name + ".vti");
      write_vti(f, grid, vtk_arrays);
      log->info("wrote {}", f.string());
    }
    // Reports so far, so a long run leaves results even if a later mesh fails.
    write_json(out_dir / "results.json", info, result.rows);
    write_csv(out_dir / "results.csv", info, result.rows);
  }
  log->info("wrote {} and {}", (out_dir / "results.json").string(), (out_dir / "results.csv").string());
  return result;
}

}  // namespace vfe::apps

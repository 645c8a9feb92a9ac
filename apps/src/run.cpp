#include "run.hpp"

#include "dump_reader.hpp"
#include "foam_writer.hpp"
#include "run_plan.hpp"
#include "scene_mesh.hpp"
#include "scene_particles.hpp"
#include "timing.hpp"
#include "vtk_writer.hpp"

#include <CLI/CLI.hpp>
#include <vfe/engine.hpp>
#include <vfe/measures.hpp>

#include <spdlog/logger.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <limits>
#include <optional>
#include <ostream>
#include <thread>
#include <iostream>
#include <memory>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;
std::string g3(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
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
  const bool foam = opt.foam || cfg.foam;
  const fs::path out_dir = opt.output.value_or(cfg.output);
  if (cfg.series) return run_series(cfg, opt);

  MethodPlan plan = plan_methods(cfg, opt);
  const std::vector<MethodSpec>& methods = plan.methods;
  const MethodSpec& reference = plan.reference;
  const bool reference_listed = plan.reference_listed;
  const int threads_used = plan.threads;
  auto engine_options = [&](const MethodSpec& m) { return plan.options_for(m); };

  // Particles (read or generated), and the options they need (orientation=given with
  // quaternions) before the config's own.
  if (cfg.generate)
    log->info("generating {} particles of shape '{}'", cfg.generate->count, cfg.generate->shape);
  else
    log->info("reading {}", cfg.particles_file.string());
  auto t0 = Clock::now();
  const SceneParticles frame = load_particles(cfg);
  const double mean_d = frame.mean_diameter();
  log->info("{} {}particles at timestep {} (mean {}diameter {}), {} in {:.0f} ms", frame.n,
            frame.shaped() ? "shaped " : "", frame.timestep, frame.shaped() ? "volume-equivalent " : "", g3(mean_d),
            cfg.generate ? "generated" : "read", ms_since(t0));
  if (!frame.options.empty()) {
    add_particle_options(plan, cfg, opt, frame.options);
    log->info("particle options: {} (the config's options win)", frame.options);
  }
  const vfe::ParticleView particles = frame.view();
  check_coupling_velocities(cfg, frame);

  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir))
    throw std::runtime_error(out_dir.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output or 'output:'");

  RunInfo info;
  info.scene = cfg.name;
  info.particles_file = frame.source_name;
  info.timestep = frame.timestep;
  info.particles = frame.n;
  info.particle_volume = frame.total_volume();
  info.mean_diameter = mean_d;
  info.reference = reference.label;
  info.threads = threads_used;
  info.repeats = repeats;
  info.options = plan.global;
  info.version = vfe_version();

  RunResult result;
  result.output = out_dir;

  const std::vector<MeshSpec> meshes = scene_meshes(cfg, cfg.chi, mean_d);

  const std::string reference_title = plan.reference_title();

  for (std::size_t mesh_index = 0; mesh_index < meshes.size(); ++mesh_index) {
    const MeshSpec& mesh = meshes[mesh_index];
    const bool poly = mesh.type == "polymesh";       // an OpenFOAM case
    const bool rectilinear = mesh.type == "rectilinear";
    const std::string mesh_where = "mesh '" + mesh.name + "'";
    t0 = Clock::now();
    SceneMesh built = build_scene_mesh(mesh, &frame.box, source);
    if (poly) log->info("mesh '{}': read {} in {:.0f} ms", mesh.name, mesh.path.string(), ms_since(t0));
    // A chi mesh keeps its spacing exactly, so extending past the box is expected there.
    if (!built.note.empty()) {
      if (mesh_index < cfg.meshes.size())
        log->warn("mesh '{}': {}", mesh.name, built.note);
      else
        log->info("mesh '{}': {}", mesh.name, built.note);
    }
    const vfe::CartesianGridSpec& grid = built.grid;
    const std::unique_ptr<vfe::Engine>& engine = built.engine;
    register_shapes(cfg, *engine);
    const std::vector<double>& cell_volume = built.cell_volumes;
    const std::size_t ncells = cell_volume.size();
    std::vector<double> ref(ncells), solid(ncells), eps(ncells);
    const double cell_size = built.cube_root_of_mean_volume();
    const double chi = mean_d > 0 ? cell_size / mean_d : 0.0;
    log_mesh(*log, mesh, built, chi);
    const bool foam_here = foam && poly;
    if (foam && !poly)
      log->warn("mesh '{}' is not an OpenFOAM case: OpenFOAM field files are written for polymesh meshes only",
                mesh.name);

    std::vector<MethodField> fields;  // kept for the writers
    const bool keep_fields = vtk || foam_here;
    /// After a compute: with coupling, the weights CSV, and the field to keep.
    auto keep_field = [&](const std::string& label, const std::vector<double>& field, const std::string& opts) {
      std::vector<double> us;
      if (cfg.coupling) {
        const fs::path weights_file = out_dir / (mesh.name + "_weights_" + label + ".csv");
        write_weights_csv(weights_file, *engine, frame);
        log->info("  {}: wrote {}", label, weights_file.string());
        if (keep_fields) us = particle_velocity_field(*engine, frame);
      }
      if (keep_fields) fields.push_back({label, eps, field, opts, std::move(us)});
    };

    auto fill_row = [&](ResultRow& row, const MethodSpec& m, const std::string& opts) {
      row.mesh = mesh.name;
      row.mesh_type = mesh.type;
      row.label = m.label;
      row.method = m.method;
      row.options = opts;
      row.grid = built.cells_per_axis;  // {0, 0, 0} on a polyMesh
      row.cells = static_cast<std::int64_t>(ncells);
      row.cell_size = cell_size;
      row.chi = chi;
      row.particles = frame.n;
      row.threads = threads_used;
    };
    auto skipped_row = [&](const MethodSpec& m, const std::string& opts, const std::string& why) {
      ResultRow row;
      fill_row(row, m, opts);
      row.skipped = true;
      row.note = why;
      const double nan = std::numeric_limits<double>::quiet_NaN();
      row.time_median_ms = row.time_min_ms = row.particles_per_s = row.sub_elements_per_s = nan;
      row.accuracy.theta = row.accuracy.max_error = row.accuracy.l1 = row.accuracy.volume_error = nan;
      row.particle_volume = row.deposited_volume = row.dropped_volume = row.clipped_volume = nan;
      row.overfull_volume = nan;
      return row;
    };
    /// Row of a finished compute: timings, report, and errors against the reference if any.
    bool have_ref = false;
    bool outside_warned = false;
    auto measured_row = [&](const MethodSpec& m, const std::string& opts, const std::vector<double>& times,
                            const std::vector<double>& field) {
      const vfe::Report rep = engine->last_report();
      ResultRow row;
      fill_row(row, m, opts);
      row.repeats = static_cast<int>(times.size());
      row.time_median_ms = median(times);
      row.time_min_ms = *std::min_element(times.begin(), times.end());
      const double sec = row.time_median_ms * 1e-3;
      row.particles_per_s = sec > 0 ? static_cast<double>(frame.n) / sec : 0.0;
      row.sub_elements_per_s = sec > 0 ? static_cast<double>(rep.sub_elements) / sec : 0.0;
      row.sub_elements = rep.sub_elements;
      row.fast_path_particles = rep.fast_path_particles;
      row.particle_grid_min = rep.particle_grid_min;
      row.particle_grid_max = rep.particle_grid_max;
      row.accuracy = vfe::compare_fields(field, have_ref ? ref : field, cell_volume, rep.particle_volume);
      if (!have_ref) {
        const double nan = std::numeric_limits<double>::quiet_NaN();
        row.accuracy.theta = row.accuracy.max_error = row.accuracy.l1 = nan;
        row.accuracy.cells_compared = 0;
      }
      row.particle_volume = rep.particle_volume;
      row.deposited_volume = rep.deposited_volume;
      row.dropped_volume = rep.dropped_volume;
      row.clipped_volume = rep.clipped_volume;
      row.outside_particles = rep.outside_particles;
      const OverfullFacts overfull = overfull_facts(*engine);
      row.overfull_cells = overfull.cells;
      row.overfull_volume = overfull.volume;
      warn_overfull(*log, mesh.name, m.label, overfull, rep.particle_volume);
      const std::string outside = engine->option("outside");
      if (rep.outside_particles > 0 && !outside_warned) {
        outside_warned = true;
        log->warn("mesh '{}': {} of {} particles lie partly outside the mesh (outside={}{})", mesh.name,
                  rep.outside_particles, frame.n, outside,
                  outside == "drop" ? ": their outside volume is lost" : ": their outside volume is kept in the mesh");
      }
      if (rep.dropped_volume > 0)
        log->warn("  {}: {} particle(s) lie partly outside mesh '{}'; outside={} dropped {} of their volume "
                  "({:.3e} of the particle volume)",
                  m.label, rep.outside_particles, mesh.name, outside, g3(rep.dropped_volume),
                  rep.particle_volume > 0 ? rep.dropped_volume / rep.particle_volume : 0.0);
      else if (rep.outside_particles > 0)
        log->info("  {}: {} particle(s) lie partly outside mesh '{}' (outside={})", m.label, rep.outside_particles,
                  mesh.name, outside);
      if (rep.clipped_volume > 0)
        log->info("  {}: the void fraction was clipped at alpha_min={} in some cells ({} of solid volume)", m.label,
                  engine->option("alpha_min"), g3(rep.clipped_volume));
      return row;
    };
    auto unsupported = [&](const vfe::Error& e) { return e.status() == VFE_ERROR_UNSUPPORTED; };

    // Reference, once (and timed once more when it is not one of the methods).
    std::optional<ResultRow> reference_row;
    {
      const std::string opts = engine_options(reference);
      try {
        engine->configure(opts);
        t0 = Clock::now();
        engine->compute(particles, ref);
        const double first_ms = ms_since(t0);
        have_ref = true;
        log->info("  reference {}: {:.3f} ms", reference.label, first_ms);
        if (!reference_listed) {
          t0 = Clock::now();
          engine->compute(particles, solid);
          const std::vector<double> times{ms_since(t0)};
          engine->void_fraction(eps);
          reference_row = measured_row(reference, opts, times, solid);
          reference_row->is_reference = true;
          keep_field(reference.label, ref, opts);
        }
      } catch (const vfe::Error& e) {
        if (!unsupported(e)) throw vfe::Error(e.status(), mesh_where + ", reference '" + reference.label + "': " + e.what());
        log->warn("mesh '{}': reference '{}' is not supported here ({}); errors against it are not computed",
                  mesh.name, reference.label, e.what());
        if (!reference_listed) {
          reference_row = skipped_row(reference, opts, e.what());
          reference_row->is_reference = true;
        }
      }
    }

    std::vector<ResultRow> mesh_rows;
    for (const auto& m : methods) {
      const std::string opts = engine_options(m);
      try {
        engine->configure(opts);
        engine->compute(particles, solid);  // warm-up
      } catch (const vfe::Error& e) {
        if (!unsupported(e)) throw vfe::Error(e.status(), mesh_where + ", method '" + m.label + "': " + e.what());
        log->warn("mesh '{}': method '{}' skipped: {}", mesh.name, m.label, e.what());
        ResultRow row = skipped_row(m, opts, e.what());
        row.is_reference = m.label == reference.label;
        mesh_rows.push_back(std::move(row));
        continue;
      }
      with_mesh_context(mesh, "method '" + m.label + "'", [&] {
        std::vector<double> times;
        times.reserve(static_cast<std::size_t>(repeats));
        for (int r = 0; r < repeats; ++r) {
          const auto t = Clock::now();
          engine->compute(particles, solid);
          times.push_back(ms_since(t));
        }
        // The void fraction (untimed) also sets the report's clipped volume.
        engine->void_fraction(eps);
        ResultRow row = measured_row(m, opts, times, solid);
        row.is_reference = m.label == reference.label;
        log->info("  {}: {:.3f} ms per compute (median of {}), theta {:.3e}", m.label, row.time_median_ms, repeats,
                  row.accuracy.theta);
        keep_field(m.label, solid, opts);
        mesh_rows.push_back(std::move(row));
      });
    }
    if (reference_row) mesh_rows.push_back(std::move(*reference_row));

    if (opt.table) {
      char title[768];
      if (poly || rectilinear)
        std::snprintf(title, sizeof title,
                      "\n%s / mesh %s: %s of %lld cells%s, mean cell size %s (mean chi = %.2f), %lld particles, "
                      "%d thread(s), median of %d, reference %s",
                      cfg.name.c_str(), mesh.name.c_str(), poly ? "polyMesh" : "rectilinear grid",
                      static_cast<long long>(ncells), lattice_note(mesh, built), g3(cell_size).c_str(), chi,
                      static_cast<long long>(frame.n), threads_used, repeats, reference_title.c_str());
      else
        std::snprintf(title, sizeof title,
                      "\n%s / mesh %s: %lld x %lld x %lld cells of %s (chi = %.2f), %lld particles, %d thread(s), "
                      "median of %d, reference %s",
                      cfg.name.c_str(), mesh.name.c_str(), static_cast<long long>(grid.cells[0]),
                      static_cast<long long>(grid.cells[1]), static_cast<long long>(grid.cells[2]),
                      g3(cell_size).c_str(), chi, static_cast<long long>(frame.n), threads_used, repeats,
                      reference_title.c_str());
      print_table(*opt.table, title, mesh_rows);
    }
    result.rows.insert(result.rows.end(), mesh_rows.begin(), mesh_rows.end());

    if (vtk) log->info("wrote {}", write_mesh_vtk(out_dir / mesh.name, built, field_arrays(fields)).string());
    if (foam_here && !fields.empty())
      write_foam_time(out_dir / mesh.name / "0", "0", fields, plan,
                      read_constraint_patches(find_polymesh_folder(mesh.path)), *log);
    // Reports so far, so a long run leaves results even if a later mesh fails.
    write_json(out_dir / "results.json", info, result.rows);
    write_csv(out_dir / "results.csv", info, result.rows);
  }
  log->info("wrote {} and {}", (out_dir / "results.json").string(), (out_dir / "results.csv").string());
  return result;
}

void set_timesteps(SceneConfig& cfg, const std::string& range) {
  const auto colon = range.find(':');
  auto bound = [&](const std::string& text) -> std::optional<std::int64_t> {
    if (text.empty()) return std::nullopt;
    std::size_t used = 0;
    std::int64_t v = 0;
    try {
      v = std::stoll(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != text.size() || text.empty())
      throw ConfigError("--timesteps " + range + ": '" + text + "' is not an integer timestep");
    return v;
  };
  if (colon == std::string::npos)
    throw ConfigError("--timesteps " + range + ": give FROM:TO, e.g. 16500:19500 or 24000: (either may be empty)");
  if (!cfg.series)
    throw ConfigError("--timesteps: " + cfg.source.string() +
                      " has one frame; a series takes particles: {files: ...} or frames: all");
  const auto from = bound(range.substr(0, colon)), to = bound(range.substr(colon + 1));
  if (from && to && *to < *from) throw ConfigError("--timesteps " + range + ": TO is before FROM");
  cfg.series->from_timestep = from;
  cfg.series->to_timestep = to;
}

CliCommand register_run(CLI::App& app) {
  struct Args {
    std::string config_file;
    std::string output;
    int threads = -1;
    int repeats = -1;
    bool quiet = false;
    bool vtk = false;
    bool foam = false;
    std::string timesteps;
    std::vector<std::string> methods;
  };
  const auto args = std::make_shared<Args>();
  CLI::App* run = app.add_subcommand("run", "Compute, time and compare the methods of a YAML scene config");
  run->add_option("config", args->config_file, "Scene config (YAML), e.g. configs/bed_mono.yaml")
      ->required();
  run->add_option("-o,--output", args->output, "Output folder (replaces the config's 'output')");
  run->add_option("-t,--threads", args->threads, "Threads, 0 = all (replaces the config's 'threads')")
      ->check(CLI::Range(0, 4096));
  run->add_option("-r,--repeats", args->repeats, "Timed computes per method (replaces the config's 'repeats')")
      ->check(CLI::Range(1, 1000000));
  run->add_flag("-q,--quiet", args->quiet, "Print only the tables, warnings and errors");
  run->add_flag("--vtk", args->vtk,
                "Also write the fields of every method as <mesh>.vti (Cartesian) or <mesh>.vtu (polyMesh) for "
                "ParaView");
  run->add_flag("--foam", args->foam,
                "Also write OpenFOAM fields <mesh>/0/voidfraction_<method> and <mesh>/0/voidfraction on "
                "polyMesh meshes");

  run->add_option("--methods", args->methods,
                  "Run only these methods (labels of the config's methods), a list; the reference is still computed")
      ->delimiter(',');
  run->add_option("--timesteps", args->timesteps,
                  "A series' timesteps FROM:TO, inclusive, either may be empty (replaces the config's 'timesteps')");

  return {run, [args] {
    SceneConfig cfg = load_config(args->config_file);
    if (!args->timesteps.empty()) set_timesteps(cfg, args->timesteps);
    keep_methods(cfg, args->methods);
    RunOptions opt;
    if (!args->output.empty()) opt.output = args->output;
    if (args->threads >= 0) opt.threads = args->threads;
    if (args->repeats >= 1) opt.repeats = args->repeats;
    opt.vtk = args->vtk;
    opt.foam = args->foam;
    opt.logger = make_app_logger(args->quiet);
    opt.table = &std::cout;
    run_scene(cfg, opt);
    return 0;
  }};
}

}  // namespace vfe::apps

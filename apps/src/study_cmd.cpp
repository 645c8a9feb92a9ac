#include "study_cmd.hpp"

#include "dump_reader.hpp"
#include "scene_particles.hpp"
#include "report.hpp"
#include "run.hpp"
#include "scene_mesh.hpp"
#include "text_format.hpp"
#include "timing.hpp"

#include <CLI/CLI.hpp>
#include <vfe/engine.hpp>

#include <spdlog/logger.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <ostream>
#include <sstream>
#include <thread>
#include <iostream>
#include <memory>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Errors below this count as 0 (the reference against itself is round-off).
constexpr double kZeroError = 1e-12;

double error_of(const StudyPoint& p) { return p.accuracy.l1 < kZeroError ? 0.0 : p.accuracy.l1; }

struct Job {
  MethodSpec spec;      ///< the family entry
  std::string setting;  ///< "" without settings
  std::string options;  ///< full engine options
};

}  // namespace

Front make_front(std::vector<std::pair<double, double>> points) {
  std::sort(points.begin(), points.end(), [](const auto& a, const auto& b) {
    return a.first < b.first || (a.first == b.first && a.second < b.second);
  });
  Front f;
  for (const auto& [t, e] : points)
    if (f.error.empty() || e < f.error.back()) {
      f.time.push_back(t);
      f.error.push_back(e);
    }
  return f;
}

double front_time_at_error(const Front& f, double e, std::string* note) {
  if (note) note->clear();
  if (f.time.empty() || e < f.error.back() || !(e > 0)) {
    if (note) *note = "n/a";
    return kNaN;
  }
  if (e >= f.error.front()) {
    if (note) *note = ">=";
    return f.time.front();
  }
  for (std::size_t i = 0; i + 1 < f.time.size(); ++i)
    if (e <= f.error[i] && e >= f.error[i + 1]) {
      const double a = std::log(f.error[i]), b = std::log(f.error[i + 1]);
      const double s = b < a && std::isfinite(b) ? (std::log(e) - a) / (b - a) : 1.0;
      return std::exp(std::log(f.time[i]) + s * (std::log(f.time[i + 1]) - std::log(f.time[i])));
    }
  return f.time.back();
}

double front_error_at_time(const Front& f, double t, std::string* note) {
  if (note) note->clear();
  if (f.time.empty() || t < f.time.front() || !(t > 0)) {
    if (note) *note = "n/a";
    return kNaN;
  }
  if (t >= f.time.back()) {
    if (note) *note = f.time.size() > 1 || t > f.time.back() ? ">=" : "";
    return f.error.back();
  }
  for (std::size_t i = 0; i + 1 < f.time.size(); ++i)
    if (t >= f.time[i] && t <= f.time[i + 1]) {
      const double a = std::log(f.time[i]), b = std::log(f.time[i + 1]);
      const double s = b > a ? (std::log(t) - a) / (b - a) : 1.0;
      if (!(f.error[i + 1] > 0)) return s < 1 ? std::exp(std::log(f.error[i])) : 0.0;
      return std::exp(std::log(f.error[i]) + s * (std::log(f.error[i + 1]) - std::log(f.error[i])));
    }
  return f.error.back();
}

void mark_pareto(std::vector<StudyPoint>& points) {
  for (auto& p : points) {
    p.pareto = !p.skipped;
    if (p.skipped) continue;
    for (const auto& q : points) {
      if (&q == &p || q.mesh != p.mesh || q.skipped) continue;
      const double tp = p.time_median_ms, tq = q.time_median_ms, ep = error_of(p), eq = error_of(q);
      if (tq <= tp && eq <= ep && (tq < tp || eq < ep)) {
        p.pareto = false;
        break;
      }
    }
  }
}

namespace {

std::vector<StudyComparison> compare(const std::vector<StudyPoint>& points, const std::string& base) {
  std::vector<StudyComparison> out;
  std::vector<std::string> meshes;
  for (const auto& p : points)
    if (std::find(meshes.begin(), meshes.end(), p.mesh) == meshes.end()) meshes.push_back(p.mesh);
  for (const auto& mesh : meshes) {
    std::vector<std::pair<double, double>> base_points;
    for (const auto& p : points)
      if (p.mesh == mesh && p.family == base && !p.skipped) base_points.emplace_back(p.time_median_ms, error_of(p));
    if (base_points.empty()) continue;
    const Front front = make_front(base_points);
    for (const auto& p : points) {
      if (p.mesh != mesh || p.family == base || p.skipped) continue;
      StudyComparison c;
      c.mesh = mesh;
      c.chi = p.chi;
      c.family = p.family;
      c.setting = p.setting;
      c.time_ms = p.time_median_ms;
      c.l1 = error_of(p);
      c.base_time_at_error = front_time_at_error(front, c.l1, &c.speedup_note);
      c.speedup = c.time_ms / c.base_time_at_error;
      c.base_error_at_time = front_error_at_time(front, c.time_ms, &c.gain_note);
      c.accuracy_gain = c.l1 > 0 ? c.l1 / c.base_error_at_time : kNaN;
      if (!(c.l1 > 0)) c.gain_note = "n/a";
      out.push_back(std::move(c));
    }
  }
  return out;
}

std::string setting_text(const StudyPoint& p) { return p.setting.empty() ? "-" : p.setting; }

void print_mesh_tables(std::ostream& out, const std::string& scene, const std::string& base,
                       const std::vector<StudyPoint>& pts, const std::vector<StudyComparison>& cmp) {
  const StudyPoint& first = pts.front();
  char title[512];
  if (first.mesh_type == "cartesian")
    std::snprintf(title, sizeof title,
                  "\n%s / mesh %s: %lld x %lld x %lld cells of %.3g (chi = %.3g), %lld particles, %d thread(s), "
                  "median of %d",
                  scene.c_str(), first.mesh.c_str(), static_cast<long long>(first.grid[0]),
                  static_cast<long long>(first.grid[1]), static_cast<long long>(first.grid[2]), first.cell_size,
                  first.chi, static_cast<long long>(first.particles), first.threads, first.repeats);
  else
    std::snprintf(title, sizeof title,
                  "\n%s / mesh %s: %s of %lld cells, mean cube root of the cell volume %.3g (chi = %.3g: that "
                  "over the mean particle diameter), %lld particles, %d thread(s), median of %d",
                  scene.c_str(), first.mesh.c_str(), first.mesh_type == "polymesh" ? "polyMesh" : "rectilinear grid",
                  static_cast<long long>(first.cells), first.cell_size, first.chi,
                  static_cast<long long>(first.particles), first.threads, first.repeats);
  out << title << '\n';
  std::vector<std::vector<std::string>> rows = {
      {"family", "setting", "ms/compute", "theta", "max|err|", "L1", "grid", "pareto"}};
  std::vector<std::string> skipped;
  for (const auto& p : pts) {
    if (p.skipped) {
      rows.push_back({p.family, setting_text(p), "skipped", "-", "-", "-", "-", ""});
      if (std::find(skipped.begin(), skipped.end(), p.note) == skipped.end()) skipped.push_back(p.note);
      continue;
    }
    rows.push_back({p.family + (p.is_reference ? " *" : ""), setting_text(p), table_number("%.3f", p.time_median_ms),
                    table_number("%.3e", p.accuracy.theta), table_number("%.3e", p.accuracy.max_error), table_number("%.3e", p.accuracy.l1),
                    grid_range(p.particle_grid_min, p.particle_grid_max), p.pareto ? "yes" : ""});
  }
  print_columns(out, rows, 2);
  for (const auto& why : skipped) out << "skipped: " << why << '\n';
  if (cmp.empty()) return;
  out << "\n" << base << " against every other point (L1; log-log interpolation along " << base << "'s front):\n";
  rows = {{"family", "setting", "ms", "L1", base + " ms at L1", "speedup", base + " L1 at ms", "L1 ratio"}};
  for (const auto& c : cmp)
    rows.push_back({c.family, c.setting.empty() ? "-" : c.setting, table_number("%.3f", c.time_ms), table_number("%.3e", c.l1),
                    table_number("%.3f", c.base_time_at_error),
                    c.speedup_note == "n/a" ? "n/a" : c.speedup_note + table_number("%.2f", c.speedup),
                    table_number("%.3e", c.base_error_at_time),
                    c.gain_note == "n/a" ? "n/a" : c.gain_note + table_number("%.2f", c.accuracy_gain)});
  print_columns(out, rows, 2);
  out << "(speedup = ms / " << base << " ms at the same L1; L1 ratio = L1 / " << base
      << " L1 at the same ms; '>=' a bound: " << base << "'s settings go no further; * reference)\n";
  out.flush();
}

}  // namespace

StudyResult run_study(const SceneConfig& cfg, const StudyOptions& opt) {
  const auto log = opt.logger ? opt.logger : make_app_logger(true);
  const std::string source = cfg.source.string();
  const int repeats = opt.repeats.value_or(cfg.repeats);
  if (repeats < 1) throw ConfigError(source + ": repeats must be >= 1 (got " + std::to_string(repeats) + ")");
  const std::vector<double> chis = opt.chi.value_or(cfg.chi);
  for (double x : chis)
    if (!(x > 0)) throw ConfigError("chi must be > 0 (got " + std::to_string(x) + ")");
  if (chis.empty() && cfg.meshes.empty())
    throw ConfigError(source + ": the study has no grid; add chi: [0.75, 1, 2, 3] (or meshes)");
  check_mesh_paths(cfg);
  const fs::path out_dir = opt.output.value_or(cfg.output);

  std::string global = scene_options(cfg, opt.threads, "", source);

  // Every (family, setting), checked on a one-cell engine before the particles are read.
  std::vector<Job> jobs;
  std::string defaults;
  int threads_used = 0;
  {
    vfe::Engine probe(vfe::CartesianGridSpec{});
    defaults = probe.options();
    auto options_of = [&](const MethodSpec& m, const std::string& setting, const std::string& what) {
      const std::string o = merge_options({defaults, global, "method=" + m.method, m.options, setting});
      try {
        probe.configure(o);
      } catch (const vfe::Error& e) {
        throw ConfigError(source + ": " + what + " '" + m.label + "'" +
                          (setting.empty() ? std::string() : " setting '" + setting + "'") + ": " + e.what());
      }
      return o;
    };
    (void)options_of(cfg.reference, "", "reference");
    SceneConfig selected = cfg;
    keep_methods(selected, opt.families);
    for (const auto& m : selected.methods) {
      if (m.settings.empty()) jobs.push_back({m, "", options_of(m, "", "method")});
      for (const auto& s : m.settings) jobs.push_back({m, s, options_of(m, s, "method")});
    }
    probe.configure(merge_options({defaults, global}));
    const int t = std::stoi(probe.option("threads"));
    const unsigned hc = std::thread::hardware_concurrency();
    threads_used = t > 0 ? t : (hc ? static_cast<int>(hc) : 1);
  }
  log->info("reading {}", cfg.generate ? std::string("generated particles") : cfg.particles_file.string());
  const SceneParticles frame = load_particles(cfg);
  // Options the particles need (orientation=given with quaternions), before the config's own.
  if (!frame.options.empty()) {
    global = scene_options(cfg, opt.threads, frame.options, source);
    for (Job& job : jobs) job.options = merge_options({defaults, global, "method=" + job.spec.method, job.spec.options, job.setting});
  }
  const std::string reference_options =
      merge_options({defaults, global, "method=" + cfg.reference.method, cfg.reference.options});
  const double mean_d = frame.mean_diameter();
  if (!chis.empty() && !(mean_d > 0))
    throw ConfigError(source + ": chi needs particles to size the cells (the frame has none)");
  const vfe::ParticleView particles = frame.view();
  log->info("{} particles (mean diameter {:.4g}); {} points per grid, {} timed computes each", frame.n, mean_d,
            jobs.size(), repeats);

  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir))
    throw std::runtime_error(out_dir.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output or 'output:'");

  const std::vector<MeshSpec> meshes = scene_meshes(cfg, chis, mean_d);

  StudyResult result;
  result.output = out_dir;
  for (const MeshSpec& mesh : meshes) {
    SceneMesh built = build_scene_mesh(mesh, &frame.box, source);
    vfe::Engine& engine = *built.engine;
    register_shapes(cfg, engine);
    const std::vector<double>& cell_volume = built.cell_volumes;
    const std::size_t ncells = cell_volume.size();
    std::vector<double> ref(ncells), solid(ncells);
    // Cartesian cells are all alike; elsewhere the cell size is the mean cube root of the
    // cell volumes (chi then says what a typical particle meets, not the largest cells).
    const bool uniform = mesh.type == "cartesian";
    const double cell_size =
        uniform ? std::cbrt(cell_volume.empty() ? 0.0 : cell_volume[0]) : built.mean_cube_root_volume();
    const double chi = mean_d > 0 ? cell_size / mean_d : 0.0;
    if (uniform)
      log->info("mesh '{}': {} x {} x {} cells of {:.4g} (chi = {:.3g})", mesh.name, built.grid.cells[0],
                built.grid.cells[1], built.grid.cells[2], cell_size, chi);
    else
      log->info("mesh '{}': {} of {} cells, mean cube root of the cell volume {:.4g} (chi = {:.3g})", mesh.name,
                built.polymesh() ? "polyMesh" : "rectilinear grid", ncells, cell_size, chi);
    with_mesh_context(mesh, "reference '" + cfg.reference.label + "'", [&] {
      engine.configure(reference_options);
      engine.compute(particles, ref);
    });
    const double particle_volume = engine.last_report().particle_volume;

    // Warm-up and errors, one point after the other; then the timed computes in turns
    // (every point once per round), so drifts of a shared machine touch all alike.
    std::vector<StudyPoint> pts(jobs.size());
    for (std::size_t i = 0; i < jobs.size(); ++i) {
      const Job& job = jobs[i];
      StudyPoint& p = pts[i];
      p.mesh = mesh.name;
      p.mesh_type = mesh.type;
      p.family = job.spec.label;
      p.method = job.spec.method;
      p.setting = job.setting;
      p.options = job.options;
      p.is_reference = job.options == reference_options;
      p.chi = chi;
      p.cell_size = cell_size;
      p.grid = built.cells_per_axis;
      p.cells = static_cast<std::int64_t>(ncells);
      p.particles = frame.n;
      p.threads = threads_used;
      p.repeats = repeats;
      try {
        engine.configure(job.options);
      } catch (const vfe::Error& e) {
        // A method this mesh kind does not offer (trilinear on a polyMesh) is a skipped point.
        if (e.status() != VFE_ERROR_UNSUPPORTED) throw;
        p.skipped = true;
        p.note = e.what();
        p.time_median_ms = p.time_min_ms = kNaN;
        p.accuracy.theta = p.accuracy.max_error = p.accuracy.l1 = p.accuracy.volume_error = kNaN;
        log->warn("mesh '{}': {} {} skipped: {}", mesh.name, p.family, setting_text(p), e.what());
        continue;
      }
      const auto t0 = Clock::now();
      with_mesh_context(mesh, p.family + " " + setting_text(p), [&] { engine.compute(particles, solid); });
      const double warm_up_ms = ms_since(t0);
      const vfe::Report rep = engine.last_report();
      warn_overfull(*log, mesh.name, p.family + " " + setting_text(p), overfull_facts(engine), particle_volume);
      p.accuracy = vfe::compare_fields(solid, ref, cell_volume, particle_volume);
      log->info("  {} {}: L1 {:.3e}, warm-up {:.1f} ms", p.family, setting_text(p), p.accuracy.l1, warm_up_ms);
      p.fast_path_particles = rep.fast_path_particles;
      p.sub_elements = rep.sub_elements;
      p.particle_grid_min = rep.particle_grid_min;
      p.particle_grid_max = rep.particle_grid_max;
    }
    std::vector<std::vector<double>> times(jobs.size());
    for (int r = 0; r < repeats; ++r)
      for (std::size_t i = 0; i < jobs.size(); ++i) {
        if (pts[i].skipped) continue;
        engine.configure(jobs[i].options);
        const auto t0 = Clock::now();
        engine.compute(particles, solid);
        times[i].push_back(ms_since(t0));
      }
    for (std::size_t i = 0; i < jobs.size(); ++i) {
      if (pts[i].skipped) continue;
      pts[i].time_median_ms = median(times[i]);
      pts[i].time_min_ms = *std::min_element(times[i].begin(), times[i].end());
    }
    mark_pareto(pts);
    const std::vector<StudyComparison> cmp = compare(pts, opt.base);
    if (opt.table) print_mesh_tables(*opt.table, cfg.name, opt.base, pts, cmp);
    result.points.insert(result.points.end(), pts.begin(), pts.end());
    result.comparisons.insert(result.comparisons.end(), cmp.begin(), cmp.end());
  }

  // study.csv, comparisons.csv, study.json.
  std::ostringstream csv;
  csv << "scene,mesh,chi,cell_size,nx,ny,nz,cells,particles,threads,repeats,family,method,setting,options,"
         "reference,time_median_ms,time_min_ms,theta,max_error,l1,volume_error,cells_compared,fast_path_particles,"
         "sub_elements,particle_grid_min,particle_grid_max,pareto,mesh_type,status,note\n";
  for (const auto& p : result.points)
    csv << csv_field(cfg.name) << ',' << csv_field(p.mesh) << ',' << csv_number(p.chi) << ','
        << csv_number(p.cell_size) << ',' << p.grid[0] << ',' << p.grid[1] << ',' << p.grid[2] << ',' << p.cells
        << ',' << p.particles << ',' << p.threads << ',' << p.repeats << ',' << csv_field(p.family) << ','
        << csv_field(p.method) << ',' << csv_field(p.setting) << ',' << csv_field(p.options) << ','
        << (p.is_reference ? 1 : 0) << ',' << csv_number(p.time_median_ms) << ',' << csv_number(p.time_min_ms)
        << ',' << csv_number(p.accuracy.theta) << ',' << csv_number(p.accuracy.max_error) << ','
        << csv_number(p.accuracy.l1) << ',' << csv_number(p.accuracy.volume_error) << ','
        << p.accuracy.cells_compared << ',' << p.fast_path_particles << ',' << p.sub_elements << ','
        << p.particle_grid_min << ',' << p.particle_grid_max << ',' << (p.pareto ? 1 : 0) << ','
        << csv_field(p.mesh_type) << ',' << (p.skipped ? "skipped" : "ok") << ',' << csv_field(p.note) << '\n';
  write_text_file(out_dir / "study.csv", csv.str());

  std::ostringstream ccsv;
  ccsv << "scene,mesh,chi,base,family,setting,time_ms,l1,base_time_at_error,speedup,speedup_note,"
          "base_error_at_time,accuracy_gain,gain_note\n";
  for (const auto& c : result.comparisons)
    ccsv << csv_field(cfg.name) << ',' << csv_field(c.mesh) << ',' << csv_number(c.chi) << ','
         << csv_field(opt.base) << ',' << csv_field(c.family) << ',' << csv_field(c.setting) << ','
         << csv_number(c.time_ms) << ',' << csv_number(c.l1) << ',' << csv_number(c.base_time_at_error) << ','
         << csv_number(c.speedup) << ',' << csv_field(c.speedup_note) << ',' << csv_number(c.base_error_at_time)
         << ',' << csv_number(c.accuracy_gain) << ',' << csv_field(c.gain_note) << '\n';
  write_text_file(out_dir / "comparisons.csv", ccsv.str());

  std::ostringstream js;
  js << "{\n  \"scene\": " << json_string(cfg.name) << ",\n  \"vfe_version\": " << json_string(vfe_version())
     << ",\n  \"particles_file\": " << json_string(frame.source_name)
     << ",\n  \"timestep\": " << frame.timestep << ",\n  \"particles\": " << frame.n
     << ",\n  \"mean_diameter\": " << json_number(mean_d) << ",\n  \"threads\": " << threads_used
     << ",\n  \"repeats\": " << repeats << ",\n  \"options\": " << json_string(global)
     << ",\n  \"reference\": " << json_string(cfg.reference.label) << ",\n  \"base\": " << json_string(opt.base)
     << ",\n  \"error_measure\": \"l1\",\n  \"points\": [";
  for (std::size_t i = 0; i < result.points.size(); ++i) {
    const auto& p = result.points[i];
    js << (i ? ",\n" : "\n") << "    {\"mesh\": " << json_string(p.mesh) << ", \"chi\": " << json_number(p.chi)
       << ", \"cell_size\": " << json_number(p.cell_size) << ", \"grid\": [" << p.grid[0] << ", " << p.grid[1]
       << ", " << p.grid[2] << "], \"family\": " << json_string(p.family) << ", \"method\": " << json_string(p.method)
       << ", \"setting\": " << json_string(p.setting) << ", \"options\": " << json_string(p.options)
       << ", \"reference\": " << (p.is_reference ? "true" : "false")
       << ", \"time_median_ms\": " << json_number(p.time_median_ms)
       << ", \"time_min_ms\": " << json_number(p.time_min_ms) << ", \"theta\": " << json_number(p.accuracy.theta)
       << ", \"max_error\": " << json_number(p.accuracy.max_error) << ", \"l1\": " << json_number(p.accuracy.l1)
       << ", \"volume_error\": " << json_number(p.accuracy.volume_error)
       << ", \"fast_path_particles\": " << p.fast_path_particles << ", \"sub_elements\": " << p.sub_elements
       << ", \"particle_grid_min\": " << p.particle_grid_min << ", \"particle_grid_max\": " << p.particle_grid_max
       << ", \"pareto\": " << (p.pareto ? "true" : "false") << ", \"mesh_type\": " << json_string(p.mesh_type)
       << ", \"skipped\": " << (p.skipped ? "true" : "false") << ", \"note\": " << json_string(p.note) << "}";
  }
  js << "\n  ],\n  \"comparisons\": [";
  for (std::size_t i = 0; i < result.comparisons.size(); ++i) {
    const auto& c = result.comparisons[i];
    js << (i ? ",\n" : "\n") << "    {\"mesh\": " << json_string(c.mesh) << ", \"chi\": " << json_number(c.chi)
       << ", \"family\": " << json_string(c.family) << ", \"setting\": " << json_string(c.setting)
       << ", \"time_ms\": " << json_number(c.time_ms) << ", \"l1\": " << json_number(c.l1)
       << ", \"base_time_at_error\": " << json_number(c.base_time_at_error)
       << ", \"speedup\": " << json_number(c.speedup) << ", \"speedup_note\": " << json_string(c.speedup_note)
       << ", \"base_error_at_time\": " << json_number(c.base_error_at_time)
       << ", \"accuracy_gain\": " << json_number(c.accuracy_gain) << ", \"gain_note\": " << json_string(c.gain_note)
       << "}";
  }
  js << "\n  ]\n}\n";
  write_text_file(out_dir / "study.json", js.str());
  log->info("wrote {}, {} and {}", (out_dir / "study.csv").string(), (out_dir / "comparisons.csv").string(),
            (out_dir / "study.json").string());
  return result;
}

CliCommand register_study(CLI::App& app) {
  struct Args {
    std::string study_config;
    std::string study_output;
    int study_threads = -1;
    int study_repeats = -1;
    std::vector<double> study_chi;
    std::string study_base = "pmm";
    bool study_quiet = false;
    std::vector<std::string> study_families;
  };
  const auto args = std::make_shared<Args>();
  CLI::App* study = app.add_subcommand(
      "study", "Run time against error of every method and setting of a scene at several chi (study.csv, "
               "comparisons.csv, study.json; plot with scripts/plot_study.py)");
  study->add_option("config", args->study_config, "Study config (YAML), e.g. configs/study_bed.yaml")->required();
  study->add_option("-o,--output", args->study_output, "Output folder (replaces the config's 'output')");
  study->add_option("-t,--threads", args->study_threads, "Threads, 0 = all (replaces the config's 'threads')")
      ->check(CLI::Range(0, 4096));
  study->add_option("-r,--repeats", args->study_repeats, "Timed computes per point (replaces the config's 'repeats')")
      ->check(CLI::Range(1, 1000000));
  study->add_option("--chi", args->study_chi, "Cell size / mean diameter, a list (replaces the config's 'chi')")
      ->delimiter(',')
      ->check(CLI::PositiveNumber);
  study->add_option("--base", args->study_base, "Family compared with every other point")->capture_default_str();
  study->add_option("--families", args->study_families,
                    "Run only these method families (labels of the config's methods), a list")
      ->delimiter(',');
  study->add_flag("-q,--quiet", args->study_quiet, "Print only the tables, warnings and errors");

  return {study, [args] {
    const SceneConfig cfg = load_config(args->study_config);
    StudyOptions opt;
    if (!args->study_output.empty()) opt.output = args->study_output;
    if (args->study_threads >= 0) opt.threads = args->study_threads;
    if (args->study_repeats >= 1) opt.repeats = args->study_repeats;
    if (!args->study_chi.empty()) opt.chi = args->study_chi;
    opt.base = args->study_base;
    opt.families = args->study_families;
    opt.logger = make_app_logger(args->study_quiet);
    opt.table = &std::cout;
    run_study(cfg, opt);
    return 0;
  }};
}

}  // namespace vfe::apps

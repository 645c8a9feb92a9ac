// vfe: command-line tool of the vfe library.
//   vfe run CONFIG.yaml [--output DIR] [--threads N] [--repeats N] [--quiet] [--vtk] [--foam]
//   vfe stability [--chi LIST] [--grid LIST] [--method M] [--template LIST] [--orientation LIST]
//                 [--step S] [--trajectories N] [--seed N] [--cells C] [--sweep]
//                 [--superficial-velocity U --fluid-dt DT [--diameter D]] [--output DIR]
//                 [--shape SPEC [--reference-grid N]]
//   vfe study CONFIG.yaml [--output DIR] [--threads N] [--repeats N] [--chi LIST] [--base FAMILY]
//             [--families LIST] [--quiet]
//   vfe bench [--scene bed|stream] [--dispersity mono|poly] [--particles LIST] [--chi LIST] [--threads LIST]
//             [--method LIST] [--particle-grid auto|N] [--options "key=value ..."] [--repeats N] [--seed N]
//             [--no-limits] [--output DIR] [--quiet]
//   vfe --version

#include "bench_cmd.hpp"
#include "config.hpp"
#include "run.hpp"
#include "stability_cmd.hpp"
#include "study_cmd.hpp"

#include <vfe/vfe.h>

#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>
#include <optional>
#include <string>

int main(int argc, char** argv) {
  CLI::App app{"vfe: void fraction of CFD cells from DEM particles"};
  app.name("vfe");
  app.set_version_flag("--version", std::string("vfe ") + vfe_version());
  app.require_subcommand(1);

  std::string config_file;
  std::string output;
  int threads = -1;
  int repeats = -1;
  bool quiet = false;
  bool vtk = false;
  bool foam = false;
  CLI::App* run = app.add_subcommand("run", "Compute, time and compare the methods of a YAML scene config");
  run->add_option("config", config_file, "Scene config (YAML), e.g. configs/bed_mono.yaml")
      ->required();
  run->add_option("-o,--output", output, "Output folder (replaces the config's 'output')");
  run->add_option("-t,--threads", threads, "Threads, 0 = all (replaces the config's 'threads')")
      ->check(CLI::Range(0, 4096));
  run->add_option("-r,--repeats", repeats, "Timed computes per method (replaces the config's 'repeats')")
      ->check(CLI::Range(1, 1000000));
  run->add_flag("-q,--quiet", quiet, "Print only the tables, warnings and errors");
  run->add_flag("--vtk", vtk,
                "Also write the fields of every method as <mesh>.vti (Cartesian) or <mesh>.vtu (polyMesh) for "
                "ParaView");
  run->add_flag("--foam", foam,
                "Also write OpenFOAM fields <mesh>/0/voidfraction_<method> and <mesh>/0/voidfraction on "
                "polyMesh meshes");

  vfe::apps::StabilityCommand stab;
  std::string stab_step = "1/200";
  bool stab_quiet = false;
  CLI::App* stability = app.add_subcommand(
      "stability", "Stability stress test (docs/design.md section 8): spheres moving across cells in small steps");
  stability->add_option("--chi", stab.chi, "Cell size / particle diameter, a list (e.g. 0.5,1,2)")
      ->delimiter(',')
      ->capture_default_str();
  stability->add_option("--grid", stab.grids, "Particle grids, a list of integers or auto (default auto; "
                                              "with --sweep: a ladder from 1 to 20000)")
      ->delimiter(',');
  stability->add_option("--method", stab.method, "Engine method (pmm, direct, exact, ...)")->capture_default_str();
  stability->add_option("--template", stab.templates, "Template families, a list (default: the engine's)")
      ->delimiter(',');
  stability->add_option("--orientation", stab.orientations, "Template orientations, a list (random, none)")
      ->delimiter(',');
  stability->add_option("--options", stab.options, "More engine options, \"key=value ...\"");
  stability->add_option("--step", stab_step, "Step as a fraction of the diameter (e.g. 1/200 or 0.005)")
      ->capture_default_str();
  stability->add_option("--trajectories", stab.trajectories, "Trajectories per run")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  stability->add_option("--seed", stab.seed, "Seed of the trajectories and their template orientations")
      ->capture_default_str();
  stability->add_option("--cells", stab.cells, "Distance travelled, in cells")
      ->check(CLI::Range(1e-6, 1000.0))
      ->capture_default_str();
  stability->add_option("--criterion", stab.jump_criterion, "deps_crit for J (default pi/162)")
      ->check(CLI::PositiveNumber);
  stability->add_option("--superficial-velocity", stab.superficial_velocity,
                        "U_s for the flux form psi = |deps| dx / (U_s dt_f)")
      ->check(CLI::PositiveNumber);
  stability->add_option("--fluid-dt", stab.fluid_dt, "Fluid time step dt_f for the flux form")
      ->check(CLI::PositiveNumber);
  stability->add_option("--diameter", stab.diameter,
                        "Particle diameter in the length unit of U_s dt_f (dx = chi * diameter)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  stability->add_option("--shape", stab.shape,
                        "A shaped particle instead of a sphere, e.g. \"ellipsoid 1 0.6 0.4\" (scaled to the volume-"
                        "equivalent diameter, a random orientation per trajectory; reference: exact for ellipsoids and "
                        "meshes, a fine pmm for superquadrics and clumps)");
  stability->add_option("--reference-grid", stab.reference_grid,
                        "particle_grid of the reference pmm for --shape")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{10000000}))
      ->capture_default_str();
  stability->add_flag("--sweep", stab.sweep, "Sweep the particle grids at every chi and find n_min(chi)");
  stability->add_option("-t,--threads", stab.threads, "Threads, 0 = all")->check(CLI::Range(0, 4096));
  stability->add_option("-o,--output", stab.output, "Output folder")->capture_default_str();
  stability->add_flag("-q,--quiet", stab_quiet, "Print only the tables, warnings and errors");

  std::string study_config;
  std::string study_output;
  int study_threads = -1;
  int study_repeats = -1;
  std::vector<double> study_chi;
  std::string study_base = "pmm";
  bool study_quiet = false;
  CLI::App* study = app.add_subcommand(
      "study", "Run time against error of every method and setting of a scene at several chi (study.csv, "
               "comparisons.csv, study.json; plot with scripts/plot_study.py)");
  study->add_option("config", study_config, "Study config (YAML), e.g. configs/study_bed.yaml")->required();
  study->add_option("-o,--output", study_output, "Output folder (replaces the config's 'output')");
  study->add_option("-t,--threads", study_threads, "Threads, 0 = all (replaces the config's 'threads')")
      ->check(CLI::Range(0, 4096));
  study->add_option("-r,--repeats", study_repeats, "Timed computes per point (replaces the config's 'repeats')")
      ->check(CLI::Range(1, 1000000));
  study->add_option("--chi", study_chi, "Cell size / mean diameter, a list (replaces the config's 'chi')")
      ->delimiter(',')
      ->check(CLI::PositiveNumber);
  study->add_option("--base", study_base, "Family compared with every other point")->capture_default_str();
  std::vector<std::string> study_families;
  study->add_option("--families", study_families,
                    "Run only these method families (labels of the config's methods), a list")
      ->delimiter(',');
  study->add_flag("-q,--quiet", study_quiet, "Print only the tables, warnings and errors");

  vfe::apps::BenchCommand bench_cmd;
  bool bench_quiet = false;
  CLI::App* bench = app.add_subcommand(
      "bench", "Throughput of the methods on generated scenes (packed bed or dilute stream): time, sub-elements/s, "
               "memory, thread speed-up and measured limits (bench.csv, limits.csv, bench.json)");
  bench->add_option("--scene", bench_cmd.scene, "bed (packed, solid fraction 0.58) or stream (dilute, 0.05)")
      ->capture_default_str();
  bench->add_option("--dispersity", bench_cmd.dispersity, "mono (diameter 1) or poly (uniform in [0.7, 1.3])")
      ->capture_default_str();
  bench->add_option("-n,--particles", bench_cmd.particles,
                    "Particle counts, a list (default 1e4,1e5; e.g. 1e4,1e5,1e6,4e6)")
      ->delimiter(',');
  bench->add_option("--chi", bench_cmd.chi, "Cell size / mean diameter, a list (default 2; e.g. 0.5,1,2,4)")
      ->delimiter(',');
  bench->add_option("-t,--threads", bench_cmd.threads, "Thread counts, a list (default 1,2; 0 = all)")->delimiter(',');
  bench->add_option("--method", bench_cmd.methods, "Engine methods, a list (default direct,pmm,exact), or all")->delimiter(',');
  bench->add_option("--particle-grid", bench_cmd.particle_grid, "pmm's particle_grid: auto or a count")
      ->capture_default_str();
  bench->add_option("--options", bench_cmd.options, "More engine options, \"key=value ...\" (e.g. orientation=none)");
  bench->add_option("-r,--repeats", bench_cmd.repeats, "Timed computes after one warm-up (the median is reported)")
      ->capture_default_str();
  bench->add_option("--seed", bench_cmd.seed, "Seed of the generated scene")->capture_default_str();
  bench->add_flag("!--no-limits", bench_cmd.limits, "Skip the bandwidth and locate limits (e.g. to profile a method)");
  bench->add_option("-o,--output", bench_cmd.output, "Output folder")->capture_default_str();
  bench->add_flag("-q,--quiet", bench_quiet, "Print only the table, warnings and errors");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  try {
    if (run->parsed()) {
      const vfe::apps::SceneConfig cfg = vfe::apps::load_config(config_file);
      vfe::apps::RunOptions opt;
      if (!output.empty()) opt.output = output;
      if (threads >= 0) opt.threads = threads;
      if (repeats >= 1) opt.repeats = repeats;
      opt.vtk = vtk;
      opt.foam = foam;
      opt.logger = vfe::apps::make_app_logger(quiet);
      opt.table = &std::cout;
      vfe::apps::run_scene(cfg, opt);
    } else if (study->parsed()) {
      const vfe::apps::SceneConfig cfg = vfe::apps::load_config(study_config);
      vfe::apps::StudyOptions opt;
      if (!study_output.empty()) opt.output = study_output;
      if (study_threads >= 0) opt.threads = study_threads;
      if (study_repeats >= 1) opt.repeats = study_repeats;
      if (!study_chi.empty()) opt.chi = study_chi;
      opt.base = study_base;
      opt.families = study_families;
      opt.logger = vfe::apps::make_app_logger(study_quiet);
      opt.table = &std::cout;
      vfe::apps::run_study(cfg, opt);
    } else if (bench->parsed()) {
      bench_cmd.logger = vfe::apps::make_app_logger(bench_quiet);
      bench_cmd.table = &std::cout;
      vfe::apps::run_bench(bench_cmd);
    } else if (stability->parsed()) {
      // --step takes a fraction (1/200) or a number.
      const auto slash = stab_step.find('/');
      std::size_t used = 0;
      double step = 0;
      try {
        if (slash == std::string::npos) {
          step = std::stod(stab_step, &used);
          if (used != stab_step.size()) step = 0;
        } else {
          const double a = std::stod(stab_step.substr(0, slash), &used);
          const double b = used == slash ? std::stod(stab_step.substr(slash + 1), &used) : 0;
          step = b > 0 && used == stab_step.size() - slash - 1 ? a / b : 0;
        }
      } catch (const std::exception&) {
        step = 0;
      }
      if (!(step > 0) || step > 1) {
        std::cerr << "vfe: error: --step: bad value '" << stab_step
                  << "'; expected a fraction of the diameter in (0, 1], e.g. 1/200 or 0.005\n";
        return 2;
      }
      if ((stab.superficial_velocity > 0) != (stab.fluid_dt > 0)) {
        std::cerr << "vfe: error: the flux form needs both --superficial-velocity and --fluid-dt\n";
        return 2;
      }
      stab.step = step;
      stab.logger = vfe::apps::make_app_logger(stab_quiet);
      stab.table = &std::cout;
      vfe::apps::run_stability(stab);
    }
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "vfe: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

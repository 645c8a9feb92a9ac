// vfe: command-line tool of the vfe library.
//   vfe run CONFIG.yaml [--output DIR] [--threads N] [--repeats N] [--quiet] [--vtk]
//   vfe --version

#include "config.hpp"
#include "run.hpp"

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
  CLI::App* run = app.add_subcommand("run", "Compute, time and compare the methods of a YAML scene config");
  run->add_option("config", config_file, "Scene config (YAML), e.g. configs/bed_mono.yaml")
      ->required();
  run->add_option("-o,--output", output, "Output folder (replaces the config's 'output')");
  run->add_option("-t,--threads", threads, "Threads, 0 = all (replaces the config's 'threads')")
      ->check(CLI::Range(0, 4096));
  run->add_option("-r,--repeats", repeats, "Timed computes per method (replaces the config's 'repeats')")
      ->check(CLI::Range(1, 1000000));
  run->add_flag("-q,--quiet", quiet, "Print only the tables, warnings and errors");
  run->add_flag("--vtk", vtk, "Also write the fields of every method as <mesh>.vti (ParaView)");

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
      opt.logger = vfe::apps::make_app_logger(quiet);
      opt.table = &std::cout;
      vfe::apps::run_scene(cfg, opt);
    }
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "vfe: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

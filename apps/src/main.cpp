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
#include "run.hpp"
#include "stability_cmd.hpp"
#include "study_cmd.hpp"

#include <vfe/vfe.h>

#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>
#include <vector>
#include <string>

int main(int argc, char** argv) {
  CLI::App app{"vfe: void fraction of CFD cells from DEM particles"};
  app.name("vfe");
  app.set_version_flag("--version", std::string("vfe ") + vfe_version());
  app.require_subcommand(1);
  // In the order of the help text.
  const std::vector<vfe::apps::CliCommand> commands = {vfe::apps::register_run(app), vfe::apps::register_stability(app),
                                                       vfe::apps::register_study(app), vfe::apps::register_bench(app)};

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  try {
    for (const auto& c : commands)
      if (c.command->parsed()) return c.run();
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "vfe: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

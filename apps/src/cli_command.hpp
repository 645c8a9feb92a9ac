// A command of the vfe tool as its own file registers it: the subcommand with its options,
// and what runs it once parsed.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace vfe::apps {

struct CliCommand {
  CLI::App* command = nullptr;  ///< the subcommand; command->parsed() says it was chosen
  std::function<int()> run;     ///< runs the parsed command (throws on failure); the exit code
};

}  // namespace vfe::apps

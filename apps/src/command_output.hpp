// A shell command whose standard output vfe reads as it comes (a live particle source):
// started with /bin/sh -c in a folder of our choosing, in its own process group so that
// stopping it early stops its children too.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <sys/types.h>

namespace vfe::apps {

class CommandOutput {
 public:
  /// Starts `/bin/sh -c command` in folder with its standard output on a pipe (its standard
  /// error stays ours). Throws std::runtime_error naming the command when it cannot start.
  CommandOutput(std::string command, const std::filesystem::path& folder);
  /// Stops a command still running (SIGTERM to its process group) and waits for it.
  ~CommandOutput();
  CommandOutput(const CommandOutput&) = delete;
  CommandOutput& operator=(const CommandOutput&) = delete;

  /// The read end of the command's standard output.
  std::FILE* stream() const { return stream_; }
  const std::string& command() const { return command_; }
  /// Closes the pipe and waits for the command; "" when it exited with status 0, else what
  /// happened ("exited with status 3", "was killed by signal 11 (Segmentation fault)").
  std::string wait();
  /// Stops the command (SIGTERM to its process group) and waits for it; for a source whose
  /// frames are no longer wanted.
  void stop();

 private:
  std::string command_;
  std::FILE* stream_ = nullptr;
  pid_t pid_ = -1;
};

}  // namespace vfe::apps

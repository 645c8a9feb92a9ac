#include "command_output.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

extern char** environ;

namespace vfe::apps {

CommandOutput::CommandOutput(std::string command, const std::filesystem::path& folder) : command_(std::move(command)) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw std::runtime_error("command '" + command_ + "': cannot make a pipe (" + std::strerror(errno) + ")");
  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&actions);
  posix_spawnattr_init(&attr);
  // The child's standard output is the pipe's write end (dup2 clears its close-on-exec).
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  const std::string dir = folder.empty() ? std::string(".") : folder.string();
  posix_spawn_file_actions_addchdir_np(&actions, dir.c_str());
  // Its own process group, and SIGPIPE at its default: when vfe stops reading, the command
  // and its children end instead of writing into a closed pipe.
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF);
  const char* argv[] = {"sh", "-c", command_.c_str(), nullptr};
  const int rc = ::posix_spawn(&pid_, "/bin/sh", &actions, &attr, const_cast<char* const*>(argv), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    pid_ = -1;
    throw std::runtime_error("command '" + command_ + "': cannot start it in " + dir + " (" + std::strerror(rc) +
                             "); check that the folder exists");
  }
  stream_ = ::fdopen(fds[0], "r");
  if (!stream_) {
    ::close(fds[0]);
    stop();
    throw std::runtime_error("command '" + command_ + "': cannot read its output (" + std::strerror(errno) + ")");
  }
}

CommandOutput::~CommandOutput() { stop(); }

namespace {

/// What a wait status says: "" for exit status 0.
std::string describe(int status) {
  if (WIFEXITED(status)) {
    const int code = WEXITSTATUS(status);
    if (code == 0) return "";
    return "exited with status " + std::to_string(code) +
           (code == 127 ? " (the shell did not find the program)" : code == 126 ? " (the program is not executable)" : "");
  }
  if (WIFSIGNALED(status))
    return "was killed by signal " + std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) + ")";
  return "ended with wait status " + std::to_string(status);
}

}  // namespace

std::string CommandOutput::wait() {
  if (stream_) {
    std::fclose(stream_);
    stream_ = nullptr;
  }
  if (pid_ < 0) return "";
  int status = 0;
  pid_t r;
  do {
    r = ::waitpid(pid_, &status, 0);
  } while (r < 0 && errno == EINTR);
  pid_ = -1;
  if (r < 0) return std::string("could not be waited for (") + std::strerror(errno) + ")";
  return describe(status);
}

void CommandOutput::stop() {
  if (stream_) {
    std::fclose(stream_);
    stream_ = nullptr;
  }
  if (pid_ < 0) return;
  ::kill(-pid_, SIGTERM);
  // A command that ignores SIGTERM gets SIGKILL after 2 s.
  int status = 0;
  for (int i = 0; i < 200; ++i) {
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_ || (r < 0 && errno != EINTR)) {
      pid_ = -1;
      return;
    }
    ::usleep(10000);
  }
  ::kill(-pid_, SIGKILL);
  (void)wait();
}

}  // namespace vfe::apps

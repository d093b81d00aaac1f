#pragma once
// What the cross-module tests need to run the real programs: a child process with its
// output in a log file, shell commands with their output, files.

#include <sys/resource.h>
#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mirrorscan::test_support {

// The whole file ("" when it cannot be read).
std::string ReadFile(const std::filesystem::path& path);

struct CommandResult {
  int exit_code = -1;  // 128 + signal when killed
  std::string out;     // stdout
  std::string err;     // stderr
};

// Runs `command` with /bin/sh; stderr goes through `err_file` (a scratch path).
CommandResult RunCommand(const std::string& command, const std::filesystem::path& err_file);
// Runs `command` with its stdout and stderr together in .out.
CommandResult RunCommandMerged(const std::string& command);
// The build's own `mirrorscan` with `arguments`, stdout and stderr together in .out.
CommandResult RunMirrorscan(const std::string& arguments);
// The virtual cabinet's scene `name`: boards/virtual/scenes/<name>.json in the source tree.
std::string VirtualScene(const std::string& name);

struct ChildOptions {
  std::vector<std::pair<std::string, std::string>> env;  // set in the child
  rlim_t file_size_limit = 0;  // > 0: RLIMIT_FSIZE with SIGXFSZ ignored (a "full disk")
};

// A program run as a child process, stdout and stderr to `log`. The destructor kills it
// (SIGKILL) if it still runs.
class ChildProcess {
 public:
  ChildProcess(const std::filesystem::path& program, const std::vector<std::string>& args,
               const std::filesystem::path& log, const ChildOptions& options = {});
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  std::string Log() const { return ReadFile(log_); }
  // Whether `text` shows up in the log before `deadline` (false as soon as the child exits).
  bool WaitLog(const std::string& text,
               std::chrono::milliseconds deadline = std::chrono::seconds(60));
  bool Exited();
  // The exit code (128 + signal if killed), or -1 after the deadline.
  int Wait(std::chrono::milliseconds deadline = std::chrono::seconds(60));
  void Signal(int signal);
  pid_t pid() const { return pid_; }

 private:
  std::filesystem::path log_;
  pid_t pid_ = -1;
  std::optional<int> exit_code_;
};

}  // namespace mirrorscan::test_support

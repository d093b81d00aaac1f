#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace mirrorscan::cli {

// Progress of a long command on stderr: a bar redrawn in place on a terminal, one plain
// line per stage otherwise (a log, a batch job).
class Progress {
 public:
  explicit Progress(std::string command, std::FILE* out = stderr);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // A new stage begins (ends the previous one).
  void Stage(const std::string& name);
  // How far the current stage is, in [0, 1]; drawn on a terminal only.
  void Update(double fraction);
  // Ends the current stage; prints its time.
  void Done();

 private:
  std::string command_;
  std::FILE* out_;
  bool terminal_;
  std::string stage_;
  int drawn_percent_ = -1;
  std::chrono::steady_clock::time_point stage_start_;
};

}  // namespace mirrorscan::cli

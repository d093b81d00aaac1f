#pragma once

#include <stdexcept>
#include <string>

namespace mirrorscan::cli {

// Exit statuses of `mirrorscan` (docs/meshing.md): 0 done, 1 the input cannot give the
// result (the reason on stderr), 2 usage (bad options, an input file that is missing or
// is not what it should be), 3 `process --upload`: the results are in the folder but the
// device did not take them.
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitUpload = 3;

// Thrown by a command to end with a given status; main prints what() as one line.
class CommandExit : public std::runtime_error {
 public:
  CommandExit(int status, const std::string& message)
      : std::runtime_error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

}  // namespace mirrorscan::cli

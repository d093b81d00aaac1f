#pragma once

// The levels of a virtual board's output lines, mirrored into a small shared file for
// observers outside the process: tests read the laser lines of a running mirrorscand
// (`--line-state FILE`) as a probe on the board's pins would, not its log. Layout (native
// byte order): SharedState, updated with every level the firmware drives.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace mirrorscan::hal {

class VirtualLineStates {
 public:
  static constexpr uint64_t kMagic = 0x3173656e696c736d;  // "mslines1"
  static constexpr size_t kMaxLines = 16;
  struct LineState {
    char name[24];                        // NUL-terminated
    std::atomic<int64_t> last_change_ns;  // CLOCK_MONOTONIC of the last change; 0: none
    std::atomic<uint64_t> changes;        // level changes so far
    std::atomic<uint64_t> high;           // the driven (physical) level, 1 = high
  };
  struct SharedState {
    uint64_t magic;
    std::atomic<uint64_t> count;
    LineState lines[kMaxLines];
  };

  // Creates (or truncates) `file` and maps it. Throws HardwareError kIo.
  explicit VirtualLineStates(const std::filesystem::path& file);
  ~VirtualLineStates();
  VirtualLineStates(const VirtualLineStates&) = delete;
  VirtualLineStates& operator=(const VirtualLineStates&) = delete;

  // A slot for line `name` starting at level `high`; HardwareError kInvalidArgument when
  // all kMaxLines are taken. The slot lives as long as this object.
  LineState* Add(const std::string& name, bool high);
  // Records a level the firmware drove on `slot`.
  static void Record(LineState& slot, bool high, int64_t now_ns);

  // What an observer reads from `file` (another process's lines). Throws HardwareError
  // kIo when it cannot be read or is not such a file.
  struct Observed {
    std::string name;
    bool high = false;
    int64_t last_change_ns = 0;
    uint64_t changes = 0;
  };
  static std::vector<Observed> Read(const std::filesystem::path& file);

 private:
  std::mutex mutex_;
  SharedState* state_ = nullptr;
};

}  // namespace mirrorscan::hal

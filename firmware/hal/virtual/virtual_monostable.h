#pragma once

// The virtual board's laser interlock (docs/boards.md): a retriggerable monostable. The
// firmware drives its trigger like any output line; each rising edge restarts a pulse of
// `pulse` during which the output is high, and the lasers only emit while it is. The
// output is a function of the last edge's time alone, so when the process stops
// triggering (frozen, crashed, stuck loop) it goes low `pulse` later with nothing of the
// process running, as the real part does. Thread-safe.
//
// For observers outside the process (the SIGSTOP test), the state can be mirrored into a
// small shared file (`state_file`): the magic, the pulse and the last rising edge's
// CLOCK_MONOTONIC time, each an 8-byte little-endian word, updated with every edge.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "firmware/hal/gpio_line.h"

namespace mirrorscan::hal {

class VirtualMonostable final : public GpioLine {
 public:
  static constexpr uint64_t kStateMagic = 0x6d73696e746c6b31;  // "mslkint1"-ish, version 1
  struct SharedState {
    uint64_t magic;
    int64_t pulse_ns;
    std::atomic<int64_t> last_trigger_ns;  // 0: never triggered
    std::atomic<uint64_t> triggers;
  };

  VirtualMonostable(std::chrono::nanoseconds pulse,
                    std::optional<std::filesystem::path> state_file = std::nullopt);
  ~VirtualMonostable() override;
  VirtualMonostable(const VirtualMonostable&) = delete;
  VirtualMonostable& operator=(const VirtualMonostable&) = delete;

  // GpioLine: the trigger input.
  void SetValue(bool high) override;
  bool GetValue() override;
  std::optional<GpioEdge> WaitEdge(std::chrono::nanoseconds timeout) override;

  // The output at steady time `now_ns`: high within `pulse` of the last rising edge.
  bool OutputHigh(int64_t now_ns) const;
  int64_t last_trigger_ns() const { return state_->last_trigger_ns.load(); }
  uint64_t triggers() const { return state_->triggers.load(); }
  std::chrono::nanoseconds pulse() const { return pulse_; }

 private:
  const std::chrono::nanoseconds pulse_;
  std::atomic<bool> level_{false};
  SharedState* state_;  // in the mapped file, or owned_ when there is none
  SharedState owned_{};
  size_t mapped_bytes_ = 0;
};

}  // namespace mirrorscan::hal

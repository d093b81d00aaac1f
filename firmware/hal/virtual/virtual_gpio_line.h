#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "firmware/hal/gpio_line.h"
#include "firmware/hal/virtual/virtual_line_states.h"

namespace mirrorscan::hal {

// An in-memory GPIO line for tests and the virtual cabinet. Thread-safe. Levels are
// physical (true = high), like a real line.
//
// Output side: the firmware's SetValue() is recorded; driven() and history() show it.
// Input side: a test injects levels with InjectEdge(timestamp, high) (bouncy sequences
// included); WaitEdge() returns them in order with their timestamps.
// Fault injection: SetFailing(true) makes every firmware-side call throw HardwareError.
class VirtualGpioLine final : public GpioLine {
 public:
  enum class Direction { kOutput, kInput };

  VirtualGpioLine(std::string name, Direction direction, bool initial_high = false);

  // GpioLine (the firmware side).
  void SetValue(bool high) override;
  bool GetValue() override;
  std::optional<GpioEdge> WaitEdge(std::chrono::nanoseconds timeout) override;

  // The test / simulation side.
  bool driven() const;                // the level the firmware drives now
  std::vector<bool> history() const;  // every level the firmware drove, in order
  // Steady-clock time of the last SetValue that changed the level (0: never changed), so
  // tests can measure how fast the firmware reacted.
  int64_t last_change_ns() const;
  // Sets an input's level at `timestamp_ns`; queues an edge if the level changes.
  void InjectEdge(int64_t timestamp_ns, bool high);
  void SetFailing(bool failing);
  // Mirrors the driven level into `states` (a slot named name()) from now on, for
  // observers outside the process. Throws HardwareError when it has no free slot.
  void MirrorTo(std::shared_ptr<VirtualLineStates> states);
  const std::string& name() const { return name_; }
  Direction direction() const { return direction_; }

 private:
  void ThrowIfFailing(const char* what) const;

  const std::string name_;
  const Direction direction_;
  mutable std::mutex mutex_;
  std::condition_variable edge_;
  bool level_;
  bool failing_ = false;
  std::vector<bool> history_;
  int64_t last_change_ns_ = 0;
  std::deque<GpioEdge> edges_;
  std::shared_ptr<VirtualLineStates> states_;
  VirtualLineStates::LineState* state_slot_ = nullptr;  // in states_
};

}  // namespace mirrorscan::hal

#pragma once

#include <chrono>
#include <cstdint>
#include <optional>

namespace mirrorscan::hal {

// A level change on an input line, at the physical (electrical) level.
struct GpioEdge {
  int64_t timestamp_ns = 0;  // steady clock (CLOCK_MONOTONIC), integer nanoseconds
  bool rising = false;       // true: the line went high
};

// One GPIO line at the *physical* level: true is high. Backends (gpiod/, virtual/) only
// move levels; polarity (active-low) is applied in exactly one place, ActiveLevelLine.
//
// Errors: every call throws HardwareError on failure. A line is used by one owner;
// backends are safe to call from several threads (the safety supervisor may drive an
// output while the sequencer does).
class GpioLine {
 public:
  virtual ~GpioLine() = default;

  // Drives an output line. Throws HardwareError(kInvalidArgument) on an input line.
  virtual void SetValue(bool high) = 0;
  // Reads the line's level (an output reads back what it drives).
  virtual bool GetValue() = 0;
  // Waits at most `timeout` for the next edge on an input line requested with edge
  // events; nullopt on timeout. Edges are queued: none is lost between two calls.
  virtual std::optional<GpioEdge> WaitEdge(std::chrono::nanoseconds timeout) = 0;
};

// The one place where active-low is applied: "active" means the laser is on, the LED
// lit, the button pressed, whatever the wiring.
class ActiveLevelLine {
 public:
  ActiveLevelLine(GpioLine& line, bool active_low) : line_(&line), active_low_(active_low) {}

  static bool ToPhysical(bool active, bool active_low) { return active != active_low; }
  static bool ToActive(bool physical, bool active_low) { return physical != active_low; }

  void SetActive(bool active) { line_->SetValue(ToPhysical(active, active_low_)); }
  bool IsActive() { return ToActive(line_->GetValue(), active_low_); }
  // An edge as the new active level (true: became active) and its time.
  struct Change {
    int64_t timestamp_ns;
    bool active;
  };
  std::optional<Change> WaitChange(std::chrono::nanoseconds timeout) {
    const std::optional<GpioEdge> edge = line_->WaitEdge(timeout);
    if (!edge) return std::nullopt;
    return Change{edge->timestamp_ns, ToActive(edge->rising, active_low_)};
  }

  bool active_low() const { return active_low_; }
  GpioLine& line() { return *line_; }

 private:
  GpioLine* line_;
  bool active_low_;
};

}  // namespace mirrorscan::hal

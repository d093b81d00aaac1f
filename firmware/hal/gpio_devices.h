#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "firmware/hal/button.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/debouncer.h"
#include "firmware/hal/gpio_line.h"
#include "firmware/hal/laser_bank.h"
#include "firmware/hal/led.h"

namespace mirrorscan::hal {

// Integer nanoseconds on the steady clock (the clock of GPIO edge timestamps).
using NowFn = std::function<int64_t()>;

// A GPIO output or input with its polarity, as the devices below take it.
struct OwnedGpioLine {
  std::unique_ptr<GpioLine> line;
  bool active_low = false;
};

// LaserBank on one GPIO line per laser (each a MOSFET gate). The constructor drives every
// line inactive (throws HardwareError if it cannot); the destructor calls SafeOff().
class GpioLaserBank final : public LaserBank {
 public:
  explicit GpioLaserBank(std::vector<OwnedGpioLine> lines);
  ~GpioLaserBank() override;

  int count() const override { return static_cast<int>(lines_.size()); }
  void Set(int laser, bool on) override;
  void SetAll(bool on) override;
  std::vector<bool> states() const override;
  bool SafeOff() noexcept override;

 private:
  std::vector<OwnedGpioLine> owned_;
  std::vector<ActiveLevelLine> lines_;
  std::vector<bool> states_;
  mutable std::mutex mutex_;
};

// Whether the LED is lit `elapsed_ns` after the pattern was set, and the elapsed time of
// the next change (INT64_MAX for a steady pattern). Pure, for the blinker and tests.
struct LedPhase {
  bool lit;
  int64_t next_change_ns;
};
LedPhase LedPhaseAt(LedPattern pattern, int64_t elapsed_ns);

// Led on one GPIO line; a thread of its own blinks it. Set() drives the first phase before
// it returns (throws HardwareError if it cannot); the blinker retries a failed write at
// the next change. The destructor stops the thread and switches the LED off.
class GpioLed final : public Led {
 public:
  explicit GpioLed(OwnedGpioLine line);
  ~GpioLed() override;

  void Set(LedPattern pattern) override;
  LedPattern pattern() const override;

 private:
  void Run();

  OwnedGpioLine owned_;
  ActiveLevelLine line_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  LedPattern pattern_ = LedPattern::kOff;
  int64_t since_ns_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

// The laser interlock's trigger (docs/boards.md): each Kick() is one pulse (a rising
// edge) into a retriggerable monostable whose output gates every laser's enable, so the
// lasers go dark `pulse` after the last kick whatever the process or the OS does. The
// sequencer's control loop kicks it every tick. Kick() never throws: a line that cannot
// be driven just stops the pulses, which is the safe direction.
class GpioLaserInterlock final : public LaserInterlock {
 public:
  GpioLaserInterlock(OwnedGpioLine trigger, std::chrono::milliseconds pulse);
  void Kick() noexcept override;
  std::chrono::milliseconds pulse() const { return pulse_; }

 private:
  OwnedGpioLine trigger_;
  const std::chrono::milliseconds pulse_;
};

// Button on one GPIO input line with edge events, debounced by Debouncer.
class GpioButton final : public Button {
 public:
  // `now` must be the clock of the line's edge timestamps (the steady clock for gpiod).
  GpioButton(OwnedGpioLine line, std::chrono::milliseconds debounce, NowFn now = SteadyNowNs);
  ~GpioButton() override;

  void Start(Callback callback) override;
  void Stop() noexcept override;
  bool pressed() const override { return pressed_.load(); }

  // One step of the watcher thread, public so that tests can drive it with their own
  // clock instead of Start(): reads the level at the first call, then waits at most
  // `max_wait` (less if a pending level is due) for an edge and returns the events
  // confirmed. Do not call while Started.
  std::vector<ButtonEvent> Step(std::chrono::nanoseconds max_wait);

  // The last error the watcher thread met (it keeps trying), "" if none.
  std::string last_error() const;

 private:
  OwnedGpioLine owned_;
  ActiveLevelLine line_;
  int64_t debounce_ns_;
  NowFn now_;
  std::unique_ptr<Debouncer> debouncer_;  // created at the first Step()
  std::atomic<bool> pressed_{false};
  std::atomic<bool> stop_{false};
  mutable std::mutex error_mutex_;
  std::string last_error_;
  std::thread thread_;
};

}  // namespace mirrorscan::hal

#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

// What the drive says about itself.
struct SlideStatus {
  bool enabled = false;
  bool homed = false;
  bool moving = false;
  bool fault = false;
  int fault_code = 0;  // the drive's own code; 0 when there is no fault
};

std::string ToString(const SlideStatus& status);

// The linear slide that carries the lasers. Positions are millimetres along the slide
// (world z up to a constant offset), speeds mm/s.
//
// Errors: every call throws HardwareError on failure and never crashes; a call returns
// only once the drive has acknowledged it. Each call is bounded in time by the backend's
// configured timeout and retries.
//
// Threading: implementations are safe to call from several threads; the safety
// supervisor calls Stop() and Status() from its own thread while the sequencer is
// inside Home(). Stop() also interrupts a Home() waiting in another thread.
class SlideDrive {
 public:
  virtual ~SlideDrive() = default;

  // Enables (powers) or disables the drive. Disabling a moving drive stops it.
  virtual void Enable(bool on) = 0;

  // Starts homing (the drive moves to its reference at 0 mm) and returns at once.
  virtual void StartHome() = 0;

  // StartHome(), then polls Status() every `poll` until the drive is homed and still.
  // Throws HardwareError: kFault if the drive faults (with its code), kTimeout after
  // `timeout` (the drive is stopped first), kIo/kTimeout if the link fails, and kAborted
  // if Stop() is called meanwhile.
  void Home(std::chrono::nanoseconds timeout,
            std::chrono::nanoseconds poll = std::chrono::milliseconds(10));

  // Sets the speed for the next and the current move, in mm/s (> 0).
  virtual void SetSpeed(double mm_per_s) = 0;

  // Starts a move to `target_mm` at the set speed and returns at once; the drive stops
  // by itself at the target. The direction follows from the current position.
  virtual void Start(double target_mm) = 0;

  // Stops the drive now. Use for aborts as well as normal ends.
  void Stop() {
    stop_generation_.fetch_add(1, std::memory_order_relaxed);
    DoStop();
  }

  // Clears a latched fault. Whether the drive also needs Enable(true) again depends on
  // the drive; the simulated one keeps its enable level.
  virtual void ResetFault() = 0;

  // The position readback in mm.
  virtual double Position() = 0;

  virtual SlideStatus Status() = 0;

 protected:
  virtual void DoStop() = 0;

 private:
  std::atomic<uint64_t> stop_generation_{0};
};

}  // namespace mirrorscan::hal

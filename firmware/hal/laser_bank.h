#pragma once

#include <vector>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

// The 1–3 line lasers (each switched by a MOSFET). Lasers are numbered 0..count()-1.
//
// Errors: Set/SetAll throw HardwareError (kInvalidArgument for a bad index, kIo if a line
// cannot be driven). SafeOff() never throws. Thread-safe: the safety supervisor calls
// SafeOff() from its own thread.
class LaserBank {
 public:
  virtual ~LaserBank() = default;

  virtual int count() const = 0;
  virtual void Set(int laser, bool on) = 0;
  virtual void SetAll(bool on) = 0;
  // What the firmware last commanded for each laser (index = laser). After a failed
  // write the state is not trusted to be off; SafeOff() is the way back.
  virtual std::vector<bool> states() const = 0;
  // The safe state: drives every line inactive, trying each line even if another one
  // fails, and never throws. Returns true if every line was driven off.
  virtual bool SafeOff() noexcept = 0;
};

// The lasers' hardware interlock (docs/boards.md): a retriggerable monostable gating every
// laser's enable. Kick() restarts its pulse; without kicks the lasers go dark a pulse
// after the last one, whatever the software does. Never throws.
class LaserInterlock {
 public:
  virtual ~LaserInterlock() = default;
  virtual void Kick() noexcept = 0;
};

}  // namespace mirrorscan::hal

#pragma once

#include <string>

namespace mirrorscan::hal {

// What the status LED shows. Timing (see docs/gpio.md): slow blink 1 Hz (500 ms on,
// 500 ms off) = busy; fast blink 5 Hz (100/100 ms) = scanning; fault = two 100 ms flashes
// then 700 ms dark, repeated.
enum class LedPattern { kOff, kOn, kBlinkSlow, kBlinkFast, kFault };

std::string ToString(LedPattern pattern);

// The status LED. Set() throws HardwareError if the line cannot be driven.
class Led {
 public:
  virtual ~Led() = default;
  virtual void Set(LedPattern pattern) = 0;
  virtual LedPattern pattern() const = 0;
};

}  // namespace mirrorscan::hal

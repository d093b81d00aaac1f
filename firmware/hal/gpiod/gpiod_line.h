#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "firmware/hal/gpio_line.h"

namespace mirrorscan::hal {

// A GpioLine on libgpiod v1 (character device), requested with consumer "mirrorscand".
// The calls are thin: levels stay physical (polarity is ActiveLevelLine's job), libgpiod
// errors become HardwareError(kIo) naming chip, line and role.
class GpiodLine final : public GpioLine {
 public:
  enum class Direction { kOutput, kInputWithEdges };

  // Opens `chip` (a name like "gpiochip0", a path or a number) and requests line `offset`.
  // `role` ("laser[0]", "led", "button") goes into error messages. An output starts at
  // `initial_high`. Throws HardwareError(kIo) if the chip or the line is unavailable.
  GpiodLine(const std::string& chip, unsigned int offset, Direction direction,
            const std::string& role, bool initial_high = false);
  ~GpiodLine() override;

  void SetValue(bool high) override;
  bool GetValue() override;
  std::optional<GpioEdge> WaitEdge(std::chrono::nanoseconds timeout) override;

 private:
  struct Impl;
  [[noreturn]] void Fail(const std::string& what, const std::exception& e) const;

  std::string where_;  // "gpio gpiochip0 line 17 (laser[0])"
  Direction direction_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mirrorscan::hal

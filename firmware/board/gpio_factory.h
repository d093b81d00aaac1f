#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "firmware/hal/gpio_config.h"
#include "firmware/hal/gpio_devices.h"

namespace mirrorscan::board {

// The lines of one board, requested and owned, with their polarity.
struct GpioLines {
  std::vector<hal::OwnedGpioLine> lasers;  // index = laser number
  hal::OwnedGpioLine led;
  hal::OwnedGpioLine button;
  hal::OwnedGpioLine interlock;  // null line: the board has none
};

// Requests every line of `config` from `backend` (normally config.backend). Outputs start
// at their inactive level (lasers off, LED dark). kGpiod failing is a HardwareError
// naming chip and line: never a silent fallback to kVirtual. With kVirtual the lines are
// hal::VirtualGpioLine (firmware/hal/virtual), named "laser[i]", "led", "button"; the button
// idles released; the interlock is always there, a VirtualMonostable of the configured
// pulse (mirrored to `interlock_state_file` when given), and with `line_state_file` the
// output lines (lasers, LED) mirror their levels into it (VirtualLineStates).
GpioLines MakeGpioLines(const hal::GpioConfig& config, hal::GpioBackend backend,
                        const std::optional<std::filesystem::path>& interlock_state_file = {},
                        const std::optional<std::filesystem::path>& line_state_file = {});

// The devices built on those lines.
struct GpioDevices {
  std::unique_ptr<hal::GpioLaserBank> lasers;
  std::unique_ptr<hal::GpioLed> led;
  std::unique_ptr<hal::GpioButton> button;
  std::unique_ptr<hal::GpioLaserInterlock> interlock;  // null: the board has none
};
GpioDevices MakeGpioDevices(const hal::GpioConfig& config, GpioLines lines);

}  // namespace mirrorscan::board

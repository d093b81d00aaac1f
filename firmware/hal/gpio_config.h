#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/config/json_reader.h"

namespace mirrorscan::hal {

// Which GpioLine implementation board.json asks for.
enum class GpioBackend { kGpiod, kVirtual };

// One line on the chip and its polarity.
struct GpioLineConfig {
  int line = 0;             // offset on the chip
  bool active_low = false;  // true: driving/reading low means "on"/"pressed"
};

// board.json's "gpio" object (docs/gpio.md has the keys, an example and the wiring).
struct GpioConfig {
  GpioBackend backend = GpioBackend::kGpiod;
  std::string chip = "gpiochip0";
  std::vector<GpioLineConfig> lasers;  // 1–3, index = laser number
  GpioLineConfig led;
  GpioLineConfig button;
  int debounce_ms = 20;  // the button's
  // The laser interlock (docs/boards.md): the trigger input of a retriggerable monostable
  // whose output gates every laser's enable; the lasers only light while the firmware's
  // control loop keeps pulsing it. `interlock_pulse_ms` is the monostable's pulse as built
  // (its RC); the virtual board models that pulse. Absent on a gpiod board: no interlock
  // (the daemon warns). Virtual boards always have one (default pulse 45 ms).
  std::optional<GpioLineConfig> interlock;
  int interlock_pulse_ms = 45;
};

// Parses and validates the "gpio" object; errors are ConfigError naming the key
// ("board.json: gpio.lasers[1].line: line 17 is also gpio.lasers[0].line").
GpioConfig ParseGpioConfig(const JsonReader& gpio);
// Reads board.json and parses its "gpio" object.
GpioConfig LoadGpioConfig(const std::filesystem::path& board_json);

}  // namespace mirrorscan::hal

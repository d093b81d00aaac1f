#pragma once

#include <filesystem>
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
};

// Parses and validates the "gpio" object; errors are ConfigError naming the key
// ("board.json: gpio.lasers[1].line: line 17 is also gpio.lasers[0].line").
GpioConfig ParseGpioConfig(const JsonReader& gpio);
// Reads board.json and parses its "gpio" object.
GpioConfig LoadGpioConfig(const std::filesystem::path& board_json);

}  // namespace mirrorscan::hal

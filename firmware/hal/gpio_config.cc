#include "firmware/hal/gpio_config.h"

#include <map>
#include <string>

namespace mirrorscan::hal {
namespace {

constexpr int kMaxLine = 511;

GpioLineConfig ReadLine(const JsonReader& r) {
  GpioLineConfig c;
  c.line = r.Integer("line", std::nullopt, 0, kMaxLine);
  c.active_low = r.Bool("active_low", false);
  return c;
}

}  // namespace

GpioConfig ParseGpioConfig(const JsonReader& gpio) {
  gpio.AllowOnly({"backend", "chip", "lasers", "led", "button", "interlock"});
  GpioConfig c;
  c.backend = gpio.Choice("backend", {"gpiod", "virtual"}) == "gpiod" ? GpioBackend::kGpiod
                                                                      : GpioBackend::kVirtual;
  c.chip = gpio.String("chip");
  if (c.chip.empty()) gpio.Fail("chip", "must not be empty");

  // Every line is used once; the error names the later key and the earlier one.
  std::map<int, std::string> used;
  auto claim = [&](const JsonReader& r, const GpioLineConfig& line) {
    const auto [it, inserted] = used.emplace(line.line, r.KeyPath("line"));
    if (!inserted) {
      r.Fail("line", "line " + std::to_string(line.line) + " is also " + it->second);
    }
  };

  const std::vector<JsonReader> lasers = gpio.Objects("lasers");
  if (lasers.empty() || lasers.size() > 3) {
    gpio.Fail("lasers", "expected 1 to 3 lasers, got " + std::to_string(lasers.size()));
  }
  for (const JsonReader& laser : lasers) {
    laser.AllowOnly({"line", "active_low"});
    c.lasers.push_back(ReadLine(laser));
    claim(laser, c.lasers.back());
  }

  const JsonReader led = gpio.Object("led");
  led.AllowOnly({"line", "active_low"});
  c.led = ReadLine(led);
  claim(led, c.led);

  const JsonReader button = gpio.Object("button");
  button.AllowOnly({"line", "active_low", "debounce_ms"});
  c.button = ReadLine(button);
  c.debounce_ms = button.Integer("debounce_ms", 20, 1, 1000);
  claim(button, c.button);

  if (gpio.Has("interlock")) {
    const JsonReader interlock = gpio.Object("interlock");
    interlock.AllowOnly({"line", "pulse_ms"});
    GpioLineConfig line = ReadLine(interlock);
    claim(interlock, line);
    c.interlock = line;
    // Above 50 ms a frozen process would keep the lasers on longer than the safety case
    // allows; below 20 ms a loaded control loop (10 ms tick) would trip it while scanning.
    c.interlock_pulse_ms = interlock.Integer("pulse_ms", std::nullopt, 20, 50);
  }
  return c;
}

GpioConfig LoadGpioConfig(const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  const JsonReader board(json, board_json.string());
  return ParseGpioConfig(board.Object("gpio"));
}

}  // namespace mirrorscan::hal

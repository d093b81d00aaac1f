#include "firmware/hal/gpio_config.h"

#include <functional>
#include <string>

#include <gtest/gtest.h>

namespace mirrorscan::hal {
namespace {

const std::string kVirtualBoard = std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/board.json";

nlohmann::json Example() {
  return nlohmann::json::parse(R"({"gpio": {
    "backend": "gpiod", "chip": "gpiochip0",
    "lasers": [{"line": 17}, {"line": 27, "active_low": true}, {"line": 22}],
    "led": {"line": 23},
    "button": {"line": 24, "active_low": true, "debounce_ms": 30}}})");
}

std::string ErrorAfter(const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json board = Example();
  edit(board["gpio"]);
  try {
    ParseGpioConfig(JsonReader(board, "board.json").Object("gpio"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(GpioConfigTest, ReadsTheExample) {
  const nlohmann::json board = Example();
  const GpioConfig c = ParseGpioConfig(JsonReader(board, "board.json").Object("gpio"));
  EXPECT_EQ(c.backend, GpioBackend::kGpiod);
  EXPECT_EQ(c.chip, "gpiochip0");
  ASSERT_EQ(c.lasers.size(), 3u);
  EXPECT_EQ(c.lasers[0].line, 17);
  EXPECT_FALSE(c.lasers[0].active_low);
  EXPECT_EQ(c.lasers[1].line, 27);
  EXPECT_TRUE(c.lasers[1].active_low);
  EXPECT_EQ(c.led.line, 23);
  EXPECT_EQ(c.button.line, 24);
  EXPECT_TRUE(c.button.active_low);
  EXPECT_EQ(c.debounce_ms, 30);
}

TEST(GpioConfigTest, ReadsTheVirtualBoard) {
  const GpioConfig c = LoadGpioConfig(kVirtualBoard);
  EXPECT_EQ(c.backend, GpioBackend::kVirtual);
  EXPECT_FALSE(c.lasers.empty());
}

TEST(GpioConfigTest, DefaultsDebounceAndPolarity) {
  nlohmann::json board = Example();
  board["gpio"]["button"].erase("debounce_ms");
  board["gpio"]["button"].erase("active_low");
  const GpioConfig c = ParseGpioConfig(JsonReader(board, "board.json").Object("gpio"));
  EXPECT_EQ(c.debounce_ms, 20);
  EXPECT_FALSE(c.button.active_low);
}

TEST(GpioConfigTest, ErrorsNameTheKey) {
  EXPECT_EQ(ErrorAfter([](auto& g) { g["lasers"][2]["line"] = 17; }),
            "board.json: gpio.lasers[2].line: line 17 is also gpio.lasers[0].line");
  EXPECT_EQ(ErrorAfter([](auto& g) { g["button"]["line"] = 23; }),
            "board.json: gpio.button.line: line 23 is also gpio.led.line");
  EXPECT_EQ(ErrorAfter([](auto& g) { g["lasers"] = nlohmann::json::array(); }),
            "board.json: gpio.lasers: expected 1 to 3 lasers, got 0");
  EXPECT_EQ(ErrorAfter([](auto& g) {
              g["lasers"].push_back({{"line", 5}});
            }),
            "board.json: gpio.lasers: expected 1 to 3 lasers, got 4");
  EXPECT_EQ(ErrorAfter([](auto& g) { g["led"]["line"] = -1; }),
            "board.json: gpio.led.line: must be in [0, 511], got -1");
  EXPECT_EQ(ErrorAfter([](auto& g) { g["button"]["debounce_ms"] = 0; }),
            "board.json: gpio.button.debounce_ms: must be in [1, 1000], got 0");
  EXPECT_NE(ErrorAfter([](auto& g) {
              g["lasers"][1]["activ_low"] = true;
            }).find("board.json: gpio.lasers[1].activ_low"),
            std::string::npos);
  EXPECT_NE(ErrorAfter([](auto& g) { g["pins"] = 1; }).find("board.json: gpio.pins"),
            std::string::npos);
  EXPECT_NE(ErrorAfter([](auto& g) { g["backend"] = "sysfs"; }).find("board.json: gpio.backend"),
            std::string::npos);
  EXPECT_NE(ErrorAfter([](auto& g) { g["led"].erase("line"); }).find("board.json: gpio.led.line"),
            std::string::npos);
  EXPECT_EQ(ErrorAfter([](auto& g) { g["chip"] = ""; }),
            "board.json: gpio.chip: must not be empty");
  EXPECT_NE(ErrorAfter([](auto& g) {
              g["lasers"][0]["active_low"] = 1;
            }).find("board.json: gpio.lasers[0].active_low"),
            std::string::npos);
}

TEST(GpioConfigTest, TheInterlockIsReadAndItsPulseBounded) {
  nlohmann::json board = Example();
  board["gpio"]["interlock"] = {{"line", 25}, {"pulse_ms", 40}};
  const GpioConfig c = ParseGpioConfig(JsonReader(board, "board.json").Object("gpio"));
  ASSERT_TRUE(c.interlock.has_value());
  EXPECT_EQ(c.interlock->line, 25);
  EXPECT_EQ(c.interlock_pulse_ms, 40);
  EXPECT_FALSE(ParseGpioConfig(JsonReader(Example(), "board.json").Object("gpio")).interlock);
  EXPECT_EQ(ErrorAfter([](auto& g) {
              g["interlock"] = {{"line", 25}, {"pulse_ms", 60}};
            }),
            "board.json: gpio.interlock.pulse_ms: must be in [20, 50], got 60");
  EXPECT_EQ(ErrorAfter([](auto& g) {
              g["interlock"] = {{"line", 17}, {"pulse_ms", 45}};
            }),
            "board.json: gpio.interlock.line: line 17 is also gpio.lasers[0].line");
  for (const char* pi : {"rpi4", "rpi5"}) {
    const GpioConfig shipped =
        LoadGpioConfig(std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/" + pi + "/board.json");
    ASSERT_TRUE(shipped.interlock.has_value()) << pi;
    EXPECT_LE(shipped.interlock_pulse_ms, 50) << pi;
  }
}

}  // namespace
}  // namespace mirrorscan::hal

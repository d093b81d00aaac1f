#include "firmware/board/gpio_factory.h"

#include <string>

#include <gtest/gtest.h>

#include "firmware/hal/hardware_error.h"
#include "firmware/hal/virtual/virtual_gpio_line.h"

namespace mirrorscan::board {
namespace {

using hal::GpioBackend;
using hal::GpioConfig;
using hal::HardwareError;
using hal::VirtualGpioLine;

GpioConfig Config() {
  GpioConfig c;
  c.chip = "gpiochip0";
  c.lasers = {{17, false}, {27, true}};
  c.led = {23, true};
  c.button = {24, true};
  c.debounce_ms = 5;
  return c;
}

TEST(GpioFactoryTest, VirtualLinesStartInactive) {
  GpioLines lines = MakeGpioLines(Config(), GpioBackend::kVirtual);
  ASSERT_EQ(lines.lasers.size(), 2u);
  auto* l0 = dynamic_cast<VirtualGpioLine*>(lines.lasers[0].line.get());
  auto* l1 = dynamic_cast<VirtualGpioLine*>(lines.lasers[1].line.get());
  auto* led = dynamic_cast<VirtualGpioLine*>(lines.led.line.get());
  auto* button = dynamic_cast<VirtualGpioLine*>(lines.button.line.get());
  ASSERT_TRUE(l0 && l1 && led && button);
  EXPECT_FALSE(l0->driven());
  EXPECT_TRUE(l1->driven());        // active-low off
  EXPECT_TRUE(led->driven());       // active-low dark
  EXPECT_TRUE(button->GetValue());  // pulled up, released
  EXPECT_EQ(l1->name(), "laser[1]");
  EXPECT_EQ(button->direction(), VirtualGpioLine::Direction::kInput);
  EXPECT_TRUE(lines.lasers[1].active_low);
}

TEST(GpioFactoryTest, DevicesOnVirtualLines) {
  GpioLines lines = MakeGpioLines(Config(), GpioBackend::kVirtual);
  auto* l1 = dynamic_cast<VirtualGpioLine*>(lines.lasers[1].line.get());
  GpioDevices d = MakeGpioDevices(Config(), std::move(lines));
  d.lasers->SetAll(true);
  EXPECT_FALSE(l1->driven());
  EXPECT_TRUE(d.lasers->SafeOff());
  EXPECT_TRUE(l1->driven());
  EXPECT_FALSE(d.button->pressed());
}

// No /dev/gpiochip* here: gpiod must fail, naming chip and line, and never fall back.
TEST(GpioFactoryTest, GpiodFailureIsAnErrorNotAFallback) {
  try {
    MakeGpioLines(Config(), GpioBackend::kGpiod);
    FAIL() << "gpiod lines opened on a machine without a GPIO chip";
  } catch (const HardwareError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("gpiochip0"), std::string::npos) << message;
    EXPECT_NE(message.find("line 17"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace mirrorscan::board

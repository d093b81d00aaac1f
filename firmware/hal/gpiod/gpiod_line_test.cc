#include "firmware/hal/gpiod/gpiod_line.h"

#include <string>

#include <gtest/gtest.h>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {
namespace {

// This machine has no /dev/gpiochip*: requesting a line must fail with a HardwareError
// that names chip, line and role, not crash and not hand back a dead line.
TEST(GpiodLineTest, MissingChipFailsNamingChipAndLine) {
  for (auto direction : {GpiodLine::Direction::kOutput, GpiodLine::Direction::kInputWithEdges}) {
    try {
      GpiodLine line("gpiochip-missing-7", 17, direction, "laser[0]");
      FAIL() << "opened a chip that does not exist";
    } catch (const HardwareError& e) {
      EXPECT_EQ(e.kind(), HardwareError::Kind::kIo);
      const std::string message = e.what();
      EXPECT_NE(message.find("gpiochip-missing-7"), std::string::npos) << message;
      EXPECT_NE(message.find("line 17"), std::string::npos) << message;
      EXPECT_NE(message.find("laser[0]"), std::string::npos) << message;
      EXPECT_NE(message.find("cannot open chip"), std::string::npos) << message;
    }
  }
}

TEST(GpiodLineTest, MissingDevicePathFailsToo) {
  EXPECT_THROW(GpiodLine("/dev/gpiochip0", 4, GpiodLine::Direction::kOutput, "led"), HardwareError);
}

}  // namespace
}  // namespace mirrorscan::hal

#include "firmware/hal/virtual/virtual_gpio_line.h"

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {
namespace {

using std::chrono::milliseconds;
using Dir = VirtualGpioLine::Direction;

TEST(VirtualGpioLineTest, RecordsDrivenLevels) {
  VirtualGpioLine line("laser[0]", Dir::kOutput, true);
  EXPECT_TRUE(line.driven());
  line.SetValue(false);
  line.SetValue(true);
  EXPECT_TRUE(line.GetValue());
  EXPECT_EQ(line.history(), (std::vector<bool>{false, true}));
  EXPECT_THROW(line.WaitEdge(milliseconds(0)), HardwareError);
}

TEST(VirtualGpioLineTest, QueuesInjectedEdgesWithTimestampsIncludingBounce) {
  VirtualGpioLine line("button", Dir::kInput, true);
  EXPECT_THROW(line.SetValue(false), HardwareError);
  line.InjectEdge(100, false);
  line.InjectEdge(150, true);
  line.InjectEdge(170, true);  // no change: no edge
  line.InjectEdge(200, false);
  EXPECT_FALSE(line.GetValue());
  auto e = line.WaitEdge(milliseconds(0));
  ASSERT_TRUE(e);
  EXPECT_EQ(e->timestamp_ns, 100);
  EXPECT_FALSE(e->rising);
  e = line.WaitEdge(milliseconds(0));
  ASSERT_TRUE(e);
  EXPECT_EQ(e->timestamp_ns, 150);
  EXPECT_TRUE(e->rising);
  e = line.WaitEdge(milliseconds(0));
  ASSERT_TRUE(e);
  EXPECT_EQ(e->timestamp_ns, 200);
  EXPECT_FALSE(line.WaitEdge(milliseconds(1)));
}

TEST(VirtualGpioLineTest, WakesAWaiterInAnotherThread) {
  VirtualGpioLine line("button", Dir::kInput, false);
  std::thread injector([&] { line.InjectEdge(42, true); });
  const auto e = line.WaitEdge(std::chrono::seconds(5));
  injector.join();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->timestamp_ns, 42);
}

TEST(VirtualGpioLineTest, InjectedFaultThrows) {
  VirtualGpioLine line("led", Dir::kOutput);
  line.SetFailing(true);
  EXPECT_THROW(line.SetValue(true), HardwareError);
  EXPECT_THROW(line.GetValue(), HardwareError);
  line.SetFailing(false);
  line.SetValue(true);
  EXPECT_TRUE(line.driven());
}

}  // namespace
}  // namespace mirrorscan::hal

#include "firmware/hal/virtual/virtual_gpio_line.h"

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "firmware/hal/clock.h"
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

TEST(VirtualGpioLineTest, MirrorsItsLevelsForObserversOutsideTheProcess) {
  const std::string path = ::testing::TempDir() + "/lines_" + std::to_string(::getpid());
  {
    auto states = std::make_shared<VirtualLineStates>(path);
    VirtualGpioLine laser("laser[0]", Dir::kOutput), led("led", Dir::kOutput, true);
    laser.MirrorTo(states);
    led.MirrorTo(states);
    std::vector<VirtualLineStates::Observed> seen = VirtualLineStates::Read(path);
    ASSERT_EQ(seen.size(), 2u);
    EXPECT_EQ(seen[0].name, "laser[0]");
    EXPECT_FALSE(seen[0].high);
    EXPECT_EQ(seen[0].changes, 0u);
    EXPECT_EQ(seen[1].name, "led");
    EXPECT_TRUE(seen[1].high);

    const int64_t before = SteadyNowNs();
    laser.SetValue(true);
    laser.SetValue(true);  // no change
    EXPECT_TRUE(VirtualLineStates::Read(path)[0].high);
    laser.SetValue(false);
    seen = VirtualLineStates::Read(path);
    EXPECT_FALSE(seen[0].high);
    EXPECT_EQ(seen[0].changes, 2u);
    EXPECT_EQ(seen[0].last_change_ns, laser.last_change_ns());
    EXPECT_GE(seen[0].last_change_ns, before);
    EXPECT_EQ(seen[1].changes, 0u);
  }
  // Written by the lines, not kept in the process: the file outlives them.
  EXPECT_EQ(VirtualLineStates::Read(path)[0].changes, 2u);
  std::ofstream(path, std::ios::trunc) << "not a line state file";
  EXPECT_THROW(VirtualLineStates::Read(path), HardwareError);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace mirrorscan::hal

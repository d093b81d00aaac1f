#include "firmware/hal/virtual/virtual_monostable.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "firmware/hal/clock.h"

namespace mirrorscan::hal {
namespace {

using std::chrono::milliseconds;

TEST(VirtualMonostable, OutputFollowsTheLastRisingEdgeByItsPulse) {
  VirtualMonostable mono(milliseconds(45));
  EXPECT_FALSE(mono.OutputHigh(SteadyNowNs()));  // never triggered: lasers dark
  mono.SetValue(true);
  const int64_t edge = mono.last_trigger_ns();
  ASSERT_GT(edge, 0);
  EXPECT_TRUE(mono.OutputHigh(edge));
  EXPECT_TRUE(mono.OutputHigh(edge + 44'999'999));
  EXPECT_FALSE(mono.OutputHigh(edge + 45'000'000));
  // Holding the trigger high is not a retrigger: only edges count.
  mono.SetValue(true);
  EXPECT_EQ(mono.last_trigger_ns(), edge);
  EXPECT_EQ(mono.triggers(), 1u);
  mono.SetValue(false);
  mono.SetValue(true);
  EXPECT_EQ(mono.triggers(), 2u);
  EXPECT_GE(mono.last_trigger_ns(), edge);
}

TEST(VirtualMonostable, MirrorsItsStateForObserversOutsideTheProcess) {
  const std::string path = testing::TempDir() + "/interlock_" + std::to_string(::getpid());
  VirtualMonostable mono(milliseconds(40), path);
  mono.SetValue(true);
  mono.SetValue(false);
  const int fd = ::open(path.c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  const auto* state = static_cast<const VirtualMonostable::SharedState*>(
      ::mmap(nullptr, sizeof(VirtualMonostable::SharedState), PROT_READ, MAP_SHARED, fd, 0));
  ::close(fd);
  ASSERT_NE(state, MAP_FAILED);
  EXPECT_EQ(state->magic, VirtualMonostable::kStateMagic);
  EXPECT_EQ(state->pulse_ns, 40'000'000);
  EXPECT_EQ(state->last_trigger_ns.load(), mono.last_trigger_ns());
  mono.SetValue(true);
  EXPECT_EQ(state->triggers.load(), 2u);
  ::munmap(const_cast<VirtualMonostable::SharedState*>(state), sizeof(*state));
  ::unlink(path.c_str());
}

}  // namespace
}  // namespace mirrorscan::hal

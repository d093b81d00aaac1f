#include "firmware/hal/gpio_devices.h"

#include <condition_variable>
#include <mutex>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/hal/virtual/virtual_gpio_line.h"

namespace mirrorscan::hal {
namespace {

constexpr int64_t kMs = 1'000'000;
using Dir = VirtualGpioLine::Direction;
using std::chrono::milliseconds;

struct Bank {
  std::vector<VirtualGpioLine*> lines;
  std::unique_ptr<GpioLaserBank> bank;
};

// Three lasers: 0 and 2 active-high, 1 active-low.
Bank MakeBank() {
  Bank b;
  std::vector<OwnedGpioLine> owned;
  for (int i = 0; i < 3; ++i) {
    auto line = std::make_unique<VirtualGpioLine>("laser", Dir::kOutput, i == 1);
    b.lines.push_back(line.get());
    owned.push_back({std::move(line), i == 1});
  }
  b.bank = std::make_unique<GpioLaserBank>(std::move(owned));
  return b;
}

TEST(GpioLaserBankTest, StartsOffAndAppliesActiveLow) {
  Bank b = MakeBank();
  EXPECT_EQ(b.bank->count(), 3);
  EXPECT_EQ(b.bank->states(), (std::vector<bool>{false, false, false}));
  EXPECT_FALSE(b.lines[0]->driven());
  EXPECT_TRUE(b.lines[1]->driven());  // active-low: off is high
  b.bank->Set(1, true);
  EXPECT_FALSE(b.lines[1]->driven());
  EXPECT_EQ(b.bank->states(), (std::vector<bool>{false, true, false}));
  b.bank->SetAll(true);
  EXPECT_TRUE(b.lines[0]->driven());
  EXPECT_FALSE(b.lines[1]->driven());
  EXPECT_TRUE(b.lines[2]->driven());
  b.bank->SetAll(false);
  EXPECT_FALSE(b.lines[0]->driven());
  EXPECT_TRUE(b.lines[1]->driven());
  EXPECT_FALSE(b.lines[2]->driven());
  EXPECT_THROW(b.bank->Set(3, true), HardwareError);
  EXPECT_THROW(b.bank->Set(-1, true), HardwareError);
}

TEST(GpioLaserBankTest, SafeOffNeverThrowsAndStillSwitchesTheOthersOff) {
  Bank b = MakeBank();
  b.bank->SetAll(true);
  b.lines[0]->SetFailing(true);
  bool all_off = true;
  EXPECT_NO_THROW(all_off = b.bank->SafeOff());
  EXPECT_FALSE(all_off);
  EXPECT_TRUE(b.lines[1]->driven());   // off (active-low)
  EXPECT_FALSE(b.lines[2]->driven());  // off
  // The failed laser is not reported off.
  EXPECT_EQ(b.bank->states(), (std::vector<bool>{true, false, false}));
  EXPECT_THROW(b.bank->SetAll(false), HardwareError);
  b.lines[0]->SetFailing(false);
  EXPECT_TRUE(b.bank->SafeOff());
  EXPECT_EQ(b.bank->states(), (std::vector<bool>{false, false, false}));
}

TEST(GpioLaserBankTest, FailedSwitchOnIsNotReportedOff) {
  Bank b = MakeBank();
  b.lines[2]->SetFailing(true);
  EXPECT_THROW(b.bank->Set(2, true), HardwareError);
  EXPECT_TRUE(b.bank->states()[2]);
}

// Forwards to a line the test keeps, to look at it after the device is gone.
class ForwardingLine final : public GpioLine {
 public:
  explicit ForwardingLine(GpioLine& target) : target_(target) {}
  void SetValue(bool high) override { target_.SetValue(high); }
  bool GetValue() override { return target_.GetValue(); }
  std::optional<GpioEdge> WaitEdge(std::chrono::nanoseconds timeout) override {
    return target_.WaitEdge(timeout);
  }

 private:
  GpioLine& target_;
};

TEST(GpioLaserBankTest, DestructorSwitchesOff) {
  VirtualGpioLine line("laser", Dir::kOutput, true);
  {
    std::vector<OwnedGpioLine> owned;
    owned.push_back({std::make_unique<ForwardingLine>(line), /*active_low=*/true});
    GpioLaserBank bank(std::move(owned));
    bank.SetAll(true);
    EXPECT_FALSE(line.driven());
  }
  EXPECT_TRUE(line.driven());  // inactive (active-low)
}

TEST(GpioLedTest, DestructorSwitchesOff) {
  VirtualGpioLine line("led", Dir::kOutput);
  {
    GpioLed led({std::make_unique<ForwardingLine>(line), false});
    led.Set(LedPattern::kOn);
    EXPECT_TRUE(line.driven());
  }
  EXPECT_FALSE(line.driven());
}

TEST(GpioLaserBankTest, RefusesZeroOrMoreThanThreeLasers) {
  EXPECT_THROW(GpioLaserBank(std::vector<OwnedGpioLine>{}), HardwareError);
}

TEST(LedPhaseTest, Patterns) {
  EXPECT_FALSE(LedPhaseAt(LedPattern::kOff, 123).lit);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kOn, 123).lit);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kBlinkSlow, 0).lit);
  EXPECT_EQ(LedPhaseAt(LedPattern::kBlinkSlow, 0).next_change_ns, 500 * kMs);
  EXPECT_FALSE(LedPhaseAt(LedPattern::kBlinkSlow, 500 * kMs).lit);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kBlinkSlow, 1000 * kMs).lit);
  EXPECT_EQ(LedPhaseAt(LedPattern::kBlinkSlow, 1200 * kMs).next_change_ns, 1500 * kMs);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kBlinkFast, 50 * kMs).lit);
  EXPECT_FALSE(LedPhaseAt(LedPattern::kBlinkFast, 150 * kMs).lit);
  // Fault: lit 0–100, dark 100–200, lit 200–300, dark 300–1000.
  EXPECT_TRUE(LedPhaseAt(LedPattern::kFault, 50 * kMs).lit);
  EXPECT_FALSE(LedPhaseAt(LedPattern::kFault, 150 * kMs).lit);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kFault, 250 * kMs).lit);
  EXPECT_FALSE(LedPhaseAt(LedPattern::kFault, 900 * kMs).lit);
  EXPECT_EQ(LedPhaseAt(LedPattern::kFault, 900 * kMs).next_change_ns, 1000 * kMs);
  EXPECT_TRUE(LedPhaseAt(LedPattern::kFault, 1050 * kMs).lit);
}

TEST(GpioLedTest, SetDrivesAtOnceWithActiveLow) {
  auto line = std::make_unique<VirtualGpioLine>("led", Dir::kOutput, true);
  VirtualGpioLine* raw = line.get();
  GpioLed led({std::move(line), /*active_low=*/true});
  EXPECT_TRUE(raw->driven());  // dark
  led.Set(LedPattern::kOn);
  EXPECT_FALSE(raw->driven());
  EXPECT_EQ(led.pattern(), LedPattern::kOn);
  led.Set(LedPattern::kFault);  // starts lit
  EXPECT_FALSE(raw->driven());
  led.Set(LedPattern::kOff);
  EXPECT_TRUE(raw->driven());
  EXPECT_EQ(ToString(LedPattern::kBlinkSlow), "blink-slow");
}

// A button on a virtual line with a clock the test sets.
struct TestButton {
  VirtualGpioLine* line;
  int64_t now = 0;
  std::unique_ptr<GpioButton> button;
};

std::unique_ptr<TestButton> MakeButton(bool active_low, int debounce_ms) {
  auto t = std::make_unique<TestButton>();
  auto line = std::make_unique<VirtualGpioLine>("button", Dir::kInput, active_low);
  t->line = line.get();
  TestButton* raw = t.get();
  t->button = std::make_unique<GpioButton>(OwnedGpioLine{std::move(line), active_low},
                                           milliseconds(debounce_ms), [raw] { return raw->now; });
  return t;
}

TEST(GpioButtonTest, ActiveLowBouncyPressAndReleaseOnInjectedTimes) {
  auto t = MakeButton(/*active_low=*/true, 20);
  EXPECT_TRUE(t->button->Step(milliseconds(0)).empty());  // idles high = released
  EXPECT_FALSE(t->button->pressed());
  // Press pulls the line low, with bounce.
  for (auto [ms, high] : std::vector<std::pair<int64_t, bool>>{
           {100, false}, {101, true}, {102, false}, {104, true}, {105, false}}) {
    t->line->InjectEdge(ms * kMs, high);
  }
  t->now = 110 * kMs;
  std::vector<ButtonEvent> events;
  for (int i = 0; i < 5; ++i) {
    for (auto e : t->button->Step(milliseconds(0))) events.push_back(e);
  }
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(t->button->pressed());
  t->now = 125 * kMs;
  events = t->button->Step(milliseconds(0));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, ButtonEvent::Type::kPressed);
  EXPECT_EQ(events[0].timestamp_ns, 105 * kMs);
  EXPECT_TRUE(t->button->pressed());
  // A 3 ms glitch high while held is ignored; then a clean release.
  t->line->InjectEdge(300 * kMs, true);
  t->line->InjectEdge(303 * kMs, false);
  t->now = 400 * kMs;
  events.clear();
  for (int i = 0; i < 3; ++i) {
    for (auto e : t->button->Step(milliseconds(0))) events.push_back(e);
  }
  EXPECT_TRUE(events.empty());
  t->line->InjectEdge(500 * kMs, true);
  t->now = 520 * kMs;
  events = t->button->Step(milliseconds(0));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, ButtonEvent::Type::kReleased);
  EXPECT_EQ(events[0].timestamp_ns, 500 * kMs);
}

TEST(GpioButtonTest, ActiveHighPress) {
  auto t = MakeButton(/*active_low=*/false, 5);
  t->button->Step(milliseconds(0));
  t->line->InjectEdge(10 * kMs, true);
  t->now = 15 * kMs;
  const auto events = t->button->Step(milliseconds(0));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, ButtonEvent::Type::kPressed);
}

TEST(GpioButtonTest, ThreadDeliversThroughTheCallback) {
  auto line = std::make_unique<VirtualGpioLine>("button", Dir::kInput, true);
  VirtualGpioLine* raw = line.get();
  GpioButton button({std::move(line), /*active_low=*/true}, milliseconds(5));
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<ButtonEvent> queue;
  button.Start([&](const ButtonEvent& e) {  // only enqueues
    std::lock_guard lock(mutex);
    queue.push_back(e);
    cv.notify_all();
  });
  EXPECT_THROW(button.Start([](const ButtonEvent&) {}), HardwareError);
  // Real time here (the thread uses the steady clock): a bouncy press, stamped as the
  // kernel would stamp it, at the moment it happens.
  const int64_t t0 = SteadyNowNs();
  raw->InjectEdge(t0, false);
  raw->InjectEdge(SteadyNowNs(), true);  // bounce
  const int64_t t_last = SteadyNowNs();
  raw->InjectEdge(t_last, false);
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return !queue.empty(); }));
    EXPECT_EQ(queue[0].type, ButtonEvent::Type::kPressed);
    // Normally t_last; a slow machine (qemu) may confirm the first contact already.
    EXPECT_GE(queue[0].timestamp_ns, t0);
    EXPECT_LE(queue[0].timestamp_ns, t_last);
  }
  EXPECT_TRUE(button.pressed());
  button.Stop();
  EXPECT_EQ(button.last_error(), "");
}

}  // namespace
}  // namespace mirrorscan::hal

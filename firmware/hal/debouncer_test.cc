#include "firmware/hal/debouncer.h"

#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace mirrorscan::hal {
namespace {

constexpr int64_t kMs = 1'000'000;
using Type = ButtonEvent::Type;

// Feeds (time, active) changes, then advances to `end`; collects the events.
std::vector<ButtonEvent> Feed(Debouncer& d, const std::vector<std::pair<int64_t, bool>>& changes,
                              int64_t end) {
  std::vector<ButtonEvent> events;
  for (const auto& [t, active] : changes) {
    if (auto e = d.OnChange(t, active)) events.push_back(*e);
  }
  if (auto e = d.Advance(end)) events.push_back(*e);
  return events;
}

TEST(DebouncerTest, CleanPressAndRelease) {
  Debouncer d(20 * kMs);
  auto events = Feed(d, {{100 * kMs, true}}, 119 * kMs);
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(d.active());
  ASSERT_EQ(d.deadline_ns(), 120 * kMs);
  events = Feed(d, {}, 120 * kMs);  // exactly debounce_ms stable is enough
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, Type::kPressed);
  EXPECT_EQ(events[0].timestamp_ns, 100 * kMs);
  EXPECT_TRUE(d.active());
  EXPECT_FALSE(d.deadline_ns());

  events = Feed(d, {{500 * kMs, false}}, 530 * kMs);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, Type::kReleased);
  EXPECT_EQ(events[0].timestamp_ns, 500 * kMs);
}

TEST(DebouncerTest, BouncyPressIsOnePressTimedAtTheLastBounce) {
  Debouncer d(20 * kMs);
  // Contact bounce: five changes within 6 ms, then stable pressed.
  auto events = Feed(d,
                     {{100 * kMs, true},
                      {101 * kMs, false},
                      {103 * kMs, true},
                      {104 * kMs, false},
                      {106 * kMs, true}},
                     125 * kMs);
  EXPECT_TRUE(events.empty());  // 19 ms since the last bounce
  events = Feed(d, {}, 126 * kMs);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, Type::kPressed);
  EXPECT_EQ(events[0].timestamp_ns, 106 * kMs);
}

TEST(DebouncerTest, GlitchShorterThanTheWindowIsIgnored) {
  Debouncer d(20 * kMs);
  auto events = Feed(d, {{100 * kMs, true}, {110 * kMs, false}}, 1000 * kMs);
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(d.active());
  EXPECT_FALSE(d.deadline_ns());
}

TEST(DebouncerTest, ReleaseBounceIsDebouncedToo) {
  Debouncer d(10 * kMs, /*initial_active=*/true);
  auto events = Feed(d,
                     {{200 * kMs, false},
                      {202 * kMs, true},  // bounce back
                      {203 * kMs, false},
                      {205 * kMs, true},  // still bouncing
                      {207 * kMs, false}},
                     300 * kMs);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, Type::kReleased);
  EXPECT_EQ(events[0].timestamp_ns, 207 * kMs);
  EXPECT_FALSE(d.active());
}

TEST(DebouncerTest, ConfirmationByTheNextEdgeWithoutAdvance) {
  Debouncer d(20 * kMs);
  // The press is confirmed when the release edge arrives 50 ms later.
  auto e = d.OnChange(100 * kMs, true);
  EXPECT_FALSE(e);
  e = d.OnChange(150 * kMs, false);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->type, Type::kPressed);
  EXPECT_EQ(e->timestamp_ns, 100 * kMs);
  EXPECT_TRUE(d.active());
  EXPECT_EQ(d.deadline_ns(), 170 * kMs);
}

TEST(DebouncerTest, RepeatedAndOutOfOrderEdges) {
  Debouncer d(20 * kMs);
  EXPECT_FALSE(d.OnChange(100 * kMs, true));
  EXPECT_FALSE(d.OnChange(110 * kMs, true));  // same level: does not restart the window
  EXPECT_FALSE(d.OnChange(90 * kMs, false));  // older than the last: taken as at 100 ms
  EXPECT_FALSE(d.Advance(1000 * kMs));        // back at the stable level: nothing
  EXPECT_FALSE(d.active());
}

TEST(DebouncerTest, HeldAtStartIsNoPress) {
  Debouncer d(20 * kMs, /*initial_active=*/true, 5 * kMs);
  EXPECT_TRUE(d.active());
  EXPECT_FALSE(d.Advance(1000 * kMs));
}

}  // namespace
}  // namespace mirrorscan::hal

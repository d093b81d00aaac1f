#include "firmware/scan/drive_monitor.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::scan {
namespace {

using std::chrono::milliseconds;

// A drive whose position is a function of the clock (150 mm/s from when it was made),
// with exchanges that take time like Modbus ones: the truth every readback is judged by.
class ClockDrive final : public hal::SlideDrive {
 public:
  static constexpr double kSpeed = 150.0;  // mm/s
  explicit ClockDrive(milliseconds exchange) : exchange_(exchange) {}

  double TruePositionAt(int64_t ns) const { return kSpeed * static_cast<double>(ns - t0_) / 1e9; }

  void Enable(bool) override {}
  void StartHome() override {}
  void SetSpeed(double) override {}
  void Start(double) override {}
  void ResetFault() override {}
  double Position() override {
    // The drive latches its position halfway through the exchange (taken from the
    // exchange's real ends, so a late wake-up on a loaded machine moves both together).
    const int64_t begin = hal::SteadyNowNs();
    std::this_thread::sleep_for(exchange_);
    return TruePositionAt((begin + hal::SteadyNowNs()) / 2);
  }
  hal::SlideStatus Status() override {
    std::this_thread::sleep_for(exchange_);
    return {true, true, true, false, 0};
  }

 protected:
  void DoStop() override {}

 private:
  const milliseconds exchange_;
  const int64_t t0_ = hal::SteadyNowNs();
};

// A drive whose link answers until told to fail, then times out on every exchange.
class FailingDrive final : public hal::SlideDrive {
 public:
  explicit FailingDrive(bool answering) : answering_(answering) {}
  void Fail() { answering_ = false; }
  void Enable(bool) override {}
  void StartHome() override {}
  void SetSpeed(double) override {}
  void Start(double) override {}
  void ResetFault() override {}
  double Position() override { return Answer(), 0.0; }
  hal::SlideStatus Status() override {
    return Answer(), hal::SlideStatus{true, true, true, false, 0};
  }

 protected:
  void DoStop() override {}

 private:
  void Answer() const {
    if (!answering_) throw hal::HardwareError(hal::HardwareError::Kind::kTimeout, "link timed out");
  }
  std::atomic<bool> answering_;
};

// The silence's reason: the last answer's age against the clock, or that none came, and the
// link's error.
TEST(DriveMonitor, NotAnsweringGivesTheLastAnswersAgeAndTheError) {
  FailingDrive never(false);
  {
    const DriveMonitor monitor(never, milliseconds(10));
    std::this_thread::sleep_for(milliseconds(50));
    EXPECT_EQ(monitor.NotAnswering(hal::SteadyNowNs()),
              "drive not answering (no answer yet): link timed out");
  }
  FailingDrive drive(true);
  const DriveMonitor monitor(drive, milliseconds(10));
  std::this_thread::sleep_for(milliseconds(50));
  drive.Fail();
  const int64_t failed_ns = hal::SteadyNowNs();
  std::this_thread::sleep_for(milliseconds(200));
  const int64_t now_ns = hal::SteadyNowNs();
  int age_ms = -1;
  char error[64] = {};
  const std::string reason = monitor.NotAnswering(now_ns);
  ASSERT_EQ(std::sscanf(reason.c_str(), "drive not answering (last answer %d ms ago): %63[^\n]",
                        &age_ms, error),
            2)
      << reason;
  EXPECT_STREQ(error, "link timed out");
  // The last answer came before the failure and about a poll (10 ms) earlier; 50 ms allows
  // for a late wake-up under qemu.
  EXPECT_GE(age_ms, (now_ns - failed_ns) / 1000000) << reason;
  EXPECT_LE(age_ms, (now_ns - failed_ns) / 1000000 + 50) << reason;
}

TEST(DriveMonitor, ReadbackOfAFrameAfterTheNewestSampleDoesNotLag) {
  ClockDrive drive(milliseconds(2));
  DriveMonitor monitor(drive, milliseconds(10));
  std::this_thread::sleep_for(milliseconds(120));  // a history of ~10 samples
  // Frames exposed at random moments between polls, read at once (before the next poll),
  // as the sequencer's worker does.
  std::vector<double> errors_mm;
  for (int i = 0; i < 40; ++i) {
    std::this_thread::sleep_for(milliseconds(3 + i % 7));
    const int64_t exposure = hal::SteadyNowNs();
    errors_mm.push_back(std::abs(monitor.PositionAt(exposure) - drive.TruePositionAt(exposure)));
  }
  std::sort(errors_mm.begin(), errors_mm.end());
  // Holding the newest sample is on average half a period + the status exchange behind
  // (~1 mm at 150 mm/s, up to 1.8). Extrapolated, only the stamps' jitter is left; the
  // median is judged, as a loaded machine's late wake-ups hit single samples.
  const double median = errors_mm[errors_mm.size() / 2];
  std::printf("readback error over 40 frames at 150 mm/s: median %.3f mm, max %.3f mm\n", median,
              errors_mm.back());
  EXPECT_LT(median, 0.25);
}

TEST(DriveMonitor, ExtrapolationStopsAFewPeriodsAfterTheNewestSample) {
  ClockDrive drive(milliseconds(1));
  auto monitor = std::make_unique<DriveMonitor>(drive, milliseconds(10));
  std::this_thread::sleep_for(milliseconds(80));
  // A second later (a drive gone silent): no more than 3 periods of travel past the newest
  // sample. A poll landing between the two calls extrapolates from a newer sample, so that
  // case is taken again.
  DriveSample newest;
  double far = 0.0;
  for (int attempt = 0; attempt < 20; ++attempt) {
    newest = *monitor->Latest();
    far = monitor->PositionAt(newest.time_ns + 1'000'000'000);
    if (monitor->Latest()->time_ns == newest.time_ns) break;
  }
  EXPECT_LE(far - newest.position_mm, ClockDrive::kSpeed * 0.030 + 0.2);
  EXPECT_GE(far, newest.position_mm);
}

// The drive was sent to a target it is about to reach: a frame exposed after the newest
// sample is put at most at the target, never past it (the drive stops there).
TEST(DriveMonitor, ExtrapolationStopsAtTheTarget) {
  ClockDrive drive(milliseconds(1));
  // Slow polls, so the checks below fall between two samples.
  auto monitor = std::make_unique<DriveMonitor>(drive, milliseconds(200));
  std::this_thread::sleep_for(milliseconds(900));
  for (int attempt = 0; attempt < 5; ++attempt) {
    const DriveSample newest = *monitor->Latest();
    const int64_t later = newest.time_ns + 100'000'000;  // 15 mm of travel at 150 mm/s
    monitor->SetTarget(std::nullopt);
    const double unbounded = monitor->PositionAt(later);
    monitor->SetTarget(newest.position_mm + 5.0);
    const double bounded = monitor->PositionAt(later);
    monitor->SetTarget(newest.position_mm - 5.0);  // already past it
    const double beyond = monitor->PositionAt(later);
    if (monitor->Latest()->time_ns != newest.time_ns) continue;  // a poll came in between
    EXPECT_GT(unbounded, newest.position_mm + 10.0);
    EXPECT_NEAR(bounded, newest.position_mm + 5.0, 1e-9);
    EXPECT_NEAR(beyond, newest.position_mm, 1e-9);
    return;
  }
  FAIL() << "a poll came in between the checks five times";
}

}  // namespace
}  // namespace mirrorscan::scan

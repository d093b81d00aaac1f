#include "firmware/scan/drive_monitor.h"

#include <cmath>
#include <thread>

#include <gtest/gtest.h>

#include "firmware/hal/clock.h"

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
    // The drive latches its position halfway through the exchange.
    std::this_thread::sleep_for(exchange_ / 2);
    const double x = TruePositionAt(hal::SteadyNowNs());
    std::this_thread::sleep_for(exchange_ / 2);
    return x;
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

TEST(DriveMonitor, ReadbackOfAFrameAfterTheNewestSampleDoesNotLag) {
  ClockDrive drive(milliseconds(2));
  DriveMonitor monitor(drive, milliseconds(10));
  std::this_thread::sleep_for(milliseconds(120));  // a history of ~10 samples
  // Frames exposed at random moments between polls, read at once (before the next poll),
  // as the sequencer's worker does.
  double worst_mm = 0.0;
  for (int i = 0; i < 40; ++i) {
    std::this_thread::sleep_for(milliseconds(3 + i % 7));
    const int64_t exposure = hal::SteadyNowNs();
    const double error = monitor.PositionAt(exposure) - drive.TruePositionAt(exposure);
    worst_mm = std::max(worst_mm, std::abs(error));
  }
  // Holding the newest sample would be up to a period + an exchange behind: 1.8 mm at
  // 150 mm/s. Extrapolated from the last samples it is within jitter of the stamps.
  std::printf("worst readback error %.3f mm over 40 frames at 150 mm/s\n", worst_mm);
  EXPECT_LT(worst_mm, 0.3);
}

TEST(DriveMonitor, ExtrapolationStopsAFewPeriodsAfterTheNewestSample) {
  ClockDrive drive(milliseconds(1));
  auto monitor = std::make_unique<DriveMonitor>(drive, milliseconds(10));
  std::this_thread::sleep_for(milliseconds(80));
  const DriveSample newest = *monitor->Latest();
  // A second later (a drive gone silent): no more than 3 periods of travel past it.
  const double far = monitor->PositionAt(newest.time_ns + 1'000'000'000);
  EXPECT_LE(far - newest.position_mm, ClockDrive::kSpeed * 0.030 + 0.2);
  EXPECT_GE(far, newest.position_mm);
}

}  // namespace
}  // namespace mirrorscan::scan

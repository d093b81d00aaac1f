#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "firmware/hal/slide_drive.h"

namespace mirrorscan::scan {

// One answer of the drive: its status and position readback, the position stamped with
// the steady clock at the middle of its own exchange.
struct DriveSample {
  int64_t request_ns = 0;  // when the exchange began: later than a command sent before it
  int64_t time_ns = 0;
  double position_mm = 0.0;
  hal::SlideStatus status;
};

// Polls the drive's status and position at a steady rate on its own thread. Frames take
// their slide position from here (interpolated to their exposure time) rather than asking
// the drive per frame: a Modbus exchange costs milliseconds and may time out, and neither
// may ever hold up a camera callback. The safety supervisor watches the same samples, so
// a drive that stops answering is seen from how old the last good answer is, without any
// thread blocking on the link.
class DriveMonitor {
 public:
  DriveMonitor(hal::SlideDrive& drive, std::chrono::nanoseconds period);
  ~DriveMonitor();
  DriveMonitor(const DriveMonitor&) = delete;
  DriveMonitor& operator=(const DriveMonitor&) = delete;

  std::optional<DriveSample> Latest() const;
  // Steady time of the last good answer (0 before the first).
  int64_t last_good_ns() const;
  // The reason for a fault on silence: "drive not answering (last answer N ms ago)" (or
  // "(no answer yet)") and the last error. The age tells a lost link (growing) from a
  // monitor that was held off (just over the limit).
  std::string NotAnswering(int64_t now_ns) const;
  // The position at `time_ns`: linear between the two samples around it; after the newest
  // one, extrapolated at the last few samples' velocity (at most 3 periods ahead); the
  // oldest before the history. NaN without samples.
  double PositionAt(int64_t time_ns) const;
  // Where the drive was sent: extrapolation stops there (the drive stops at its target, and
  // the next poll may come late: under qemu a frame past the sweep's end was put 1.3 mm
  // beyond it). nullopt: no bound.
  void SetTarget(std::optional<double> target_mm);

 private:
  void Run();

  hal::SlideDrive& drive_;
  const std::chrono::nanoseconds period_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<DriveSample> history_;  // oldest first, a few seconds
  int64_t last_good_ns_ = 0;
  std::string last_error_;
  std::optional<double> target_mm_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace mirrorscan::scan

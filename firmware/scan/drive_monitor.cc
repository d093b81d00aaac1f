#include "firmware/scan/drive_monitor.h"

#include <cmath>
#include <limits>

#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::scan {
namespace {
constexpr size_t kHistory = 512;  // 5 s at 10 ms
}  // namespace

DriveMonitor::DriveMonitor(hal::SlideDrive& drive, std::chrono::nanoseconds period)
    : drive_(drive), period_(period), thread_([this] { Run(); }) {}

DriveMonitor::~DriveMonitor() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void DriveMonitor::Run() {
  std::unique_lock lock(mutex_);
  auto next = std::chrono::steady_clock::now();
  while (!stop_) {
    lock.unlock();
    DriveSample sample;
    std::string error;
    const int64_t begin_ns = hal::SteadyNowNs();
    sample.request_ns = begin_ns;
    try {
      sample.status = drive_.Status();
      sample.position_mm = drive_.Position();
      sample.time_ns = (begin_ns + hal::SteadyNowNs()) / 2;
    } catch (const std::exception& e) {
      error = e.what();
    }
    lock.lock();
    if (error.empty()) {
      history_.push_back(sample);
      if (history_.size() > kHistory) history_.pop_front();
      last_good_ns_ = hal::SteadyNowNs();
      last_error_.clear();
    } else {
      last_error_ = error;
    }
    next += period_;
    const auto now = std::chrono::steady_clock::now();
    if (next < now) next = now;  // after a slow exchange, keep the rate, do not catch up
    wake_.wait_until(lock, next, [&] { return stop_; });
  }
}

std::optional<DriveSample> DriveMonitor::Latest() const {
  std::lock_guard lock(mutex_);
  if (history_.empty()) return std::nullopt;
  return history_.back();
}

int64_t DriveMonitor::last_good_ns() const {
  std::lock_guard lock(mutex_);
  return last_good_ns_;
}

std::string DriveMonitor::last_error() const {
  std::lock_guard lock(mutex_);
  return last_error_;
}

double DriveMonitor::PositionAt(int64_t time_ns) const {
  std::lock_guard lock(mutex_);
  if (history_.empty()) return std::numeric_limits<double>::quiet_NaN();
  if (time_ns <= history_.front().time_ns) return history_.front().position_mm;
  if (time_ns >= history_.back().time_ns) return history_.back().position_mm;
  // Newest samples are the likely ones: search from the back.
  for (size_t i = history_.size() - 1; i > 0; --i) {
    const DriveSample& a = history_[i - 1];
    const DriveSample& b = history_[i];
    if (a.time_ns <= time_ns) {
      const double span = static_cast<double>(b.time_ns - a.time_ns);
      const double w = span > 0 ? static_cast<double>(time_ns - a.time_ns) / span : 0.0;
      return a.position_mm + w * (b.position_mm - a.position_mm);
    }
  }
  return history_.front().position_mm;
}

}  // namespace mirrorscan::scan

#include "firmware/scan/drive_monitor.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <spdlog/spdlog.h>

#include "common/realtime/realtime.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::scan {
namespace {
constexpr size_t kHistory = 512;  // 5 s at 10 ms
// Past the newest sample the position is extrapolated at the velocity of the last few
// samples, for at most this many poll periods (a stopped or silent drive is not
// extrapolated into the distance).
constexpr size_t kVelocitySamples = 4;
constexpr int64_t kMaxExtrapolationPeriods = 3;
}  // namespace

DriveMonitor::DriveMonitor(hal::SlideDrive& drive, std::chrono::nanoseconds period)
    : drive_(drive), period_(period), thread_([this] { Run(); }) {
  // A monitor held off by a busy machine would look like a drive gone silent.
  if (const std::string why = RunThreadFirst(thread_, 20); !why.empty())
    spdlog::warn("drive monitor: {}; on a busy machine the drive may seem silent", why);
}

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
      // Stamped at the middle of the position exchange alone: the status exchange before
      // it would date the position up to a whole exchange early.
      const int64_t position_begin_ns = hal::SteadyNowNs();
      sample.position_mm = drive_.Position();
      sample.time_ns = (position_begin_ns + hal::SteadyNowNs()) / 2;
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
    // After a slow or failed exchange (a silent drive takes its retries), keep the rate,
    // do not catch up, and leave the link free for a while: polling straight on would
    // take the drive's lock again at once, and from a real-time thread that shuts out the
    // control loop's and the supervisor's commands (Stop) for as long as the drive is
    // silent.
    if (next < now) next = now + period_ / 2;
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

std::string DriveMonitor::NotAnswering(int64_t now_ns) const {
  std::lock_guard lock(mutex_);
  const std::string age =
      last_good_ns_ == 0
          ? "no answer yet"
          : "last answer " + std::to_string((now_ns - last_good_ns_) / 1000000) + " ms ago";
  return "drive not answering (" + age + ")" + (last_error_.empty() ? "" : ": " + last_error_);
}

void DriveMonitor::SetTarget(std::optional<double> target_mm) {
  std::lock_guard lock(mutex_);
  target_mm_ = target_mm;
}

double DriveMonitor::PositionAt(int64_t time_ns) const {
  std::lock_guard lock(mutex_);
  if (history_.empty()) return std::numeric_limits<double>::quiet_NaN();
  if (time_ns <= history_.front().time_ns) return history_.front().position_mm;
  if (time_ns >= history_.back().time_ns) {
    // A frame exposed after the newest sample (the next poll has not come yet): the
    // least-squares velocity of the last few samples carries the position on.
    const DriveSample& newest = history_.back();
    const size_t n = std::min(kVelocitySamples, history_.size());
    if (n < 2) return newest.position_mm;
    double mean_t = 0.0, mean_x = 0.0;
    for (size_t i = history_.size() - n; i < history_.size(); ++i) {
      mean_t += static_cast<double>(history_[i].time_ns - newest.time_ns);
      mean_x += history_[i].position_mm;
    }
    mean_t /= static_cast<double>(n);
    mean_x /= static_cast<double>(n);
    double stt = 0.0, stx = 0.0;
    for (size_t i = history_.size() - n; i < history_.size(); ++i) {
      const double dt = static_cast<double>(history_[i].time_ns - newest.time_ns) - mean_t;
      stt += dt * dt;
      stx += dt * (history_[i].position_mm - mean_x);
    }
    if (stt <= 0.0) return newest.position_mm;
    const int64_t ahead =
        std::min<int64_t>(time_ns - newest.time_ns, kMaxExtrapolationPeriods * period_.count());
    const double velocity = stx / stt;
    const double position = newest.position_mm + velocity * static_cast<double>(ahead);
    if (!target_mm_) return position;
    // Never carried past the target (nor further from it, once beyond it).
    const double towards = *target_mm_ - newest.position_mm;
    if (towards * velocity <= 0.0) return newest.position_mm;
    return velocity > 0.0 ? std::min(position, *target_mm_) : std::max(position, *target_mm_);
  }
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

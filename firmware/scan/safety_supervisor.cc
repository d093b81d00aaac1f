#include "firmware/scan/safety_supervisor.h"

#include <algorithm>

#include <spdlog/spdlog.h>

#include "common/realtime/realtime.h"
#include "firmware/hal/clock.h"

namespace mirrorscan::scan {

SafetySupervisor::SafetySupervisor(hal::LaserBank& lasers, hal::SlideDrive& drive,
                                   const DriveMonitor& monitor, SupervisorOptions options,
                                   TripCallback on_trip)
    : lasers_(lasers),
      drive_(drive),
      monitor_(monitor),
      options_(options),
      on_trip_(std::move(on_trip)),
      thread_([this] { Run(); }) {
  // Above the drive monitor, whose answers it judges.
  if (const std::string why = RunThreadFirst(thread_, 30); !why.empty())
    spdlog::warn("supervisor: {}; on a busy machine its checks may come late", why);
}

SafetySupervisor::~SafetySupervisor() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
  lasers_.SafeOff();
}

void SafetySupervisor::Arm(const std::vector<WatchedCamera>& cameras, bool watch_drive) {
  std::lock_guard lock(mutex_);
  const int64_t now_ns = hal::SteadyNowNs();
  camera_names_.clear();
  for (size_t i = 0; i < kMaxCameras; ++i) {
    const hal::Camera* camera = i < cameras.size() ? cameras[i].camera : nullptr;
    if (i < cameras.size()) camera_names_.push_back(cameras[i].name);
    cameras_[i].store(camera);
    last_frame_clock_ns_[i].store(camera != nullptr ? camera->clock_ns() : now_ns);
    last_frame_ns_[i].store(now_ns);
  }
  watch_drive_ = watch_drive;
  armed_ns_ = now_ns;
  armed_ = true;
}

void SafetySupervisor::Disarm() {
  std::lock_guard lock(mutex_);
  armed_ = false;
  tripped_ = false;
}

void SafetySupervisor::CameraFrame(int camera) {
  if (camera < 0 || camera >= static_cast<int>(kMaxCameras)) return;
  const hal::Camera* watched = cameras_[camera].load();
  const int64_t now_ns = hal::SteadyNowNs();
  last_frame_clock_ns_[camera].store(watched != nullptr ? watched->clock_ns() : now_ns);
  last_frame_ns_[camera].store(now_ns);
}

void SafetySupervisor::RequestTrip(bool fault, const std::string& reason) noexcept {
  try {
    {
      std::lock_guard lock(mutex_);
      if (trip_requested_) return;  // the first cause is the one reported
      trip_requested_ = true;
      requested_fault_ = fault;
      requested_reason_ = reason;
      requested_ns_ = hal::SteadyNowNs();
    }
    wake_.notify_all();
  } catch (...) {
    // Allocation failed: make the lasers safe right here rather than not at all.
    lasers_.SafeOff();
  }
}

std::string SafetySupervisor::CheckArmed(int64_t now_ns) {
  const double on_s = static_cast<double>(now_ns - armed_ns_.load()) * 1e-9;
  if (on_s > options_.max_laser_on_s) {
    return "lasers on longer than max_laser_on_s (" + std::to_string(options_.max_laser_on_s) +
           " s)";
  }
  for (size_t i = 0; i < camera_names_.size(); ++i) {
    // Judged on the camera's own clock: a simulated camera on a busy host makes its
    // frames late, with its clock standing still meanwhile, and is not stalled; a real
    // sensor's clock is the steady clock.
    const hal::Camera* camera = cameras_[i].load();
    const int64_t clock_ns = camera != nullptr ? camera->clock_ns() : now_ns;
    if (clock_ns - last_frame_clock_ns_[i].load() > options_.camera_stall.count()) {
      return "camera " + camera_names_[i] + " stalled (no frame for " +
             std::to_string(options_.camera_stall.count() / 1000000) + " ms)";
    }
    if (now_ns - last_frame_ns_[i].load() > options_.camera_silent.count()) {
      return "camera " + camera_names_[i] + " stalled (no frame for " +
             std::to_string(options_.camera_silent.count() / 1000000) + " ms of steady time)";
    }
  }
  if (watch_drive_) {
    if (const std::optional<DriveSample> sample = monitor_.Latest();
        sample && sample->status.fault) {
      return "drive fault " + std::to_string(sample->status.fault_code);
    }
    if (now_ns - std::max(monitor_.last_good_ns(), armed_ns_.load()) >
        options_.drive_stale.count()) {
      return monitor_.NotAnswering(now_ns);
    }
  }
  return "";
}

void SafetySupervisor::DoTrip(bool fault, const std::string& reason, int64_t detected_ns) {
  Trip trip;
  trip.fault = fault;
  trip.reason = reason;
  trip.detected_ns = detected_ns;
  tripped_ = true;
  const bool off = lasers_.SafeOff();
  trip.safe_ns = hal::SteadyNowNs();
  armed_ = false;
  if (!off) spdlog::critical("supervisor: a laser line could not be driven off");
  spdlog::warn("supervisor: {} ({}): lasers off after {:.2f} ms", reason, fault ? "fault" : "abort",
               (trip.safe_ns - detected_ns) * 1e-6);
  try {
    drive_.Stop();
  } catch (const std::exception& e) {
    spdlog::error("supervisor: drive stop failed: {}", e.what());
  }
  on_trip_(trip);
}

void SafetySupervisor::Run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    wake_.wait_for(lock, options_.period, [&] { return stop_ || trip_requested_; });
    if (stop_) break;
    heartbeat_ns_ = hal::SteadyNowNs();
    if (trip_requested_) {
      const bool fault = requested_fault_;
      const std::string reason = requested_reason_;
      const int64_t detected_ns = requested_ns_;
      lock.unlock();
      DoTrip(fault, reason, detected_ns);
      lock.lock();
      trip_requested_ = false;
      continue;
    }
    if (!armed_) continue;
    const int64_t now_ns = hal::SteadyNowNs();
    const std::string cause = CheckArmed(now_ns);  // under the lock: Arm() cannot interleave
    if (!cause.empty()) {
      lock.unlock();
      DoTrip(true, cause, now_ns);
      lock.lock();
    }
  }
}

}  // namespace mirrorscan::scan

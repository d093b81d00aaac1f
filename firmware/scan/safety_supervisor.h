#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "firmware/hal/camera.h"
#include "firmware/hal/laser_bank.h"
#include "firmware/hal/slide_drive.h"
#include "firmware/scan/drive_monitor.h"

namespace mirrorscan::scan {

struct SupervisorOptions {
  std::chrono::nanoseconds period = std::chrono::milliseconds(5);
  double max_laser_on_s = 30.0;
  // A camera that delivers no frame for this long of its own time (Camera::clock_ns(),
  // the steady clock for a real sensor) while armed has stalled.
  std::chrono::nanoseconds camera_stall = std::chrono::milliseconds(250);
  // ... and one that delivers none for this long of steady time, whatever its own clock
  // says (a simulated camera whose thread hangs making a frame: its clock stands still).
  std::chrono::nanoseconds camera_silent = std::chrono::seconds(5);
  // No good answer from the drive for this long while armed: the link is lost.
  std::chrono::nanoseconds drive_stale = std::chrono::milliseconds(150);
};

// Why the supervisor made the outputs safe.
struct Trip {
  bool fault = true;        // false: an abort (button, API, signal)
  std::string reason;       // "drive fault 66", "camera upper stalled", "button pressed"
  int64_t detected_ns = 0;  // when the supervisor saw the cause (or it was requested)
  int64_t safe_ns = 0;      // when every laser line had been driven off
};

// Klipper's shutdown(): whatever goes wrong, the outputs go safe first, then the state
// machine hears about it. One thread with a short period watches, while armed, the
// drive's status and the age of its last answer (DriveMonitor), each camera's last frame
// and the laser on-time; anyone may RequestTrip (button, API, signals, worker errors).
// A trip calls LaserBank::SafeOff() at once, then SlideDrive::Stop(), then the trip
// callback, and disarms. Trips while disarmed still make the outputs safe.
class SafetySupervisor {
 public:
  // Runs on the supervisor's thread after the outputs are safe; must only enqueue.
  using TripCallback = std::function<void(const Trip&)>;

  SafetySupervisor(hal::LaserBank& lasers, hal::SlideDrive& drive, const DriveMonitor& monitor,
                   SupervisorOptions options, TripCallback on_trip);
  // Stops the thread and makes the lasers safe.
  ~SafetySupervisor();
  SafetySupervisor(const SafetySupervisor&) = delete;
  SafetySupervisor& operator=(const SafetySupervisor&) = delete;

  struct WatchedCamera {
    std::string name;
    const hal::Camera* camera = nullptr;  // outlives the arming
  };
  // Starts watching: the on-time from now, the cameras given (index = camera; each as if
  // it had just delivered a frame), and the drive when `watch_drive`. Call before the
  // lasers go on.
  void Arm(const std::vector<WatchedCamera>& cameras, bool watch_drive);
  // Stops watching (the sequencer switches the lasers off itself on a normal end).
  void Disarm();
  bool armed() const { return armed_.load(); }
  // A trip is being carried out or was reported and not yet followed by Disarm(): the
  // sequencer then waits for the trip's report instead of judging the half-stopped
  // hardware itself.
  bool tripped() const { return tripped_.load(); }
  // A frame from `camera` (an index given to Arm) arrived; any thread, lock-free apart
  // from reading the camera's clock.
  void CameraFrame(int camera);
  // Makes the outputs safe from the supervisor's thread within one wake-up; any thread,
  // never blocks, never throws (safe in callbacks).
  void RequestTrip(bool fault, const std::string& reason) noexcept;

  const SupervisorOptions& options() const { return options_; }
  // Steady time of the thread's last pass (for the systemd watchdog).
  int64_t heartbeat_ns() const { return heartbeat_ns_.load(); }

 private:
  void Run();
  void DoTrip(bool fault, const std::string& reason, int64_t detected_ns);
  std::string CheckArmed(int64_t now_ns);  // the cause of a trip, "" if none

  hal::LaserBank& lasers_;
  hal::SlideDrive& drive_;
  const DriveMonitor& monitor_;
  const SupervisorOptions options_;
  const TripCallback on_trip_;

  std::atomic<bool> armed_{false};
  std::atomic<bool> tripped_{false};
  std::atomic<int64_t> heartbeat_ns_{0};
  std::atomic<int64_t> armed_ns_{0};
  bool watch_drive_ = false;
  // Fixed slots, so CameraFrame never races with Arm over the container.
  static constexpr size_t kMaxCameras = 8;
  // Per camera: its own clock and the steady clock at its last frame.
  std::array<std::atomic<int64_t>, kMaxCameras> last_frame_clock_ns_{};
  std::array<std::atomic<int64_t>, kMaxCameras> last_frame_ns_{};
  std::array<std::atomic<const hal::Camera*>, kMaxCameras> cameras_{};
  std::vector<std::string> camera_names_;  // the watched cameras; set by Arm

  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  bool trip_requested_ = false;
  bool requested_fault_ = false;
  std::string requested_reason_;
  int64_t requested_ns_ = 0;
  std::thread thread_;
};

}  // namespace mirrorscan::scan

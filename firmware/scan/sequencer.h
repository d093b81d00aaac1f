#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/peaks/peaks.h"
#include "common/scan_format/scan_format.h"
#include "firmware/hal/button.h"
#include "firmware/hal/camera.h"
#include "firmware/hal/laser_bank.h"
#include "firmware/hal/led.h"
#include "firmware/hal/slide_drive.h"
#include "firmware/scan/bounded_queue.h"
#include "firmware/scan/drive_monitor.h"
#include "firmware/scan/safety_supervisor.h"
#include "firmware/scan/scan_control.h"
#include "firmware/store/scan_store.h"

namespace mirrorscan::scan {

// The hardware a sequencer drives; all outlive it. button may be null (no button).
struct SequencerDevices {
  struct NamedCamera {
    std::string name;
    hal::Camera* camera = nullptr;
  };
  std::vector<NamedCamera> cameras;  // index = camera number in the archive
  hal::LaserBank* lasers = nullptr;
  // Kicked by the control loop every tick (null: the board has none). Only the loop kicks
  // it, so a stuck loop darkens the lasers as surely as a frozen process.
  hal::LaserInterlock* interlock = nullptr;
  hal::Led* led = nullptr;
  hal::Button* button = nullptr;
  hal::SlideDrive* drive = nullptr;
};

struct SequencerOptions {
  std::string board;               // the archive header's "board"
  std::string device;              // the archive header's "device" (host name)
  std::string firmware_version;    // the archive header's "firmware_version"
  std::filesystem::path data_dir;  // its calibration.json is hashed into the header
  double sweep_start_mm = 0.0;
  double sweep_end_mm = 1800.0;
  double speed_mm_s = 100.0;
  double home_timeout_s = 30.0;
  double at_target_tolerance_mm = 1.0;
  PeakParams peaks;
  SupervisorOptions supervisor;
  std::chrono::nanoseconds drive_poll = std::chrono::milliseconds(10);
  std::chrono::nanoseconds tick = std::chrono::milliseconds(10);  // the control loop's
  std::chrono::nanoseconds first_frame_timeout = std::chrono::seconds(30);
  int peak_workers = 2;
  size_t record_queue_capacity = 64;
  double progress_interval_s = 0.25;
};

// The scan sequencer (docs/firmware.md): one control thread owns the state machine
// idle → homing → arming → sweeping → finishing → done, with fault and aborted as the
// other ends. Everything else only enqueues to it: the API (StartScan/Abort), the button,
// and the SafetySupervisor's trips. Frames flow camera callback → bounded capture queue →
// peak workers → bounded record queue → archive writer; a full queue drops the frame and
// counts it, so capture never blocks.
class Sequencer final : public ScanControl {
 public:
  // Starts the drive monitor, the supervisor, the control thread and the button watch.
  // Throws HardwareError if the button cannot be watched.
  Sequencer(SequencerDevices devices, store::ScanStore& store, SequencerOptions options);
  // Aborts a running scan (finishing its archive as "aborted"), stops every thread, and
  // leaves the lasers off and the drive stopped.
  ~Sequencer() override;
  Sequencer(const Sequencer&) = delete;
  Sequencer& operator=(const Sequencer&) = delete;

  // ScanControl.
  std::string StartScan(std::string_view origin) override;
  void Abort(std::string_view reason) override;
  ScanStatus Status() const override;
  int Subscribe(Listener listener) override;
  void Unsubscribe(int handle) override;
  CapturedFrame Capture(const std::string& camera, bool lasers_on) override;

  // The supervisor, for signal handlers and tests (RequestTrip).
  SafetySupervisor& supervisor() { return *supervisor_; }
  // True when the control loop and the supervisor have both run within `max_age_ns`:
  // what the daemon's systemd watchdog ping vouches for.
  bool Alive(int64_t max_age_ns) const;
  // The last trip (detected and safe times), for tests and logs.
  std::optional<Trip> last_trip() const;

 private:
  struct Command {
    enum class Type { kStart, kTrip, kButton };
    Type type = Type::kStart;
    std::string origin;                                // kStart
    std::shared_ptr<std::promise<std::string>> reply;  // kStart from the API
    Trip trip;                                         // kTrip
  };
  struct CapturedItem {
    int camera = 0;
    bool lasers_on = false;
    hal::Frame frame;
  };
  struct CameraCounters {
    std::atomic<uint64_t> stored{0};
    std::atomic<uint64_t> queue_dropped{0};
    uint64_t camera_dropped_at_start = 0;
  };

  void Post(Command command);
  void Loop();
  void Handle(Command& command);
  void Step();  // the state's periodic work
  void BeginScan(const std::string& origin,
                 const std::shared_ptr<std::promise<std::string>>& reply);
  void StepHoming(const DriveSample& sample);
  void StepArming();
  void StepSweeping(const DriveSample& sample);
  // Outputs safe (again), cameras stopped, queues drained, archive finished.
  void EndScan(SequencerState end, const std::string& reason);
  // The loop's own failures: outputs safe first, then the archive.
  void Fail(const std::string& reason);
  void SetState(SequencerState state, const std::string& reason = "");
  void Emit(ScanEvent::Type type);
  void StartPipeline();
  void StopCameras();
  void WorkerLoop();
  void WriterLoop();
  void OnFrame(int camera, hal::Frame frame);
  nlohmann::json Header(const std::string& origin) const;
  nlohmann::json Footer(SequencerState end, const std::string& reason) const;
  bool ScanRunning() const;

  SequencerDevices devices_;
  store::ScanStore& store_;
  const SequencerOptions options_;

  std::unique_ptr<DriveMonitor> monitor_;
  std::unique_ptr<SafetySupervisor> supervisor_;

  // Status (the API reads it from other threads).
  mutable std::mutex status_mutex_;
  ScanStatus status_;
  std::optional<Trip> last_trip_;

  // Listeners; called on the control thread under this mutex.
  std::mutex listeners_mutex_;
  std::map<int, Listener> listeners_;
  int next_listener_ = 1;

  // Commands to the control thread.
  std::mutex command_mutex_;
  std::condition_variable command_ready_;
  std::deque<Command> commands_;
  bool stop_ = false;

  // Scan state, owned by the control thread.
  std::unique_ptr<store::ScanHandle> handle_;
  int64_t state_since_ns_ = 0;
  int64_t command_ns_ = 0;  // when the last drive command of this state was sent
  bool positioning_ = false;
  int64_t last_progress_ns_ = 0;
  std::vector<std::unique_ptr<CameraCounters>> counters_;
  std::atomic<bool> recording_{false};  // frames go to the archive
  // The lasers' commanded state, owned by the control loop (OnFrame reads it instead of
  // asking the laser bank per frame): when it switched them on in this sweep and when it
  // began switching them off (steady ns, 0: not yet). A frame is lit when its exposure
  // began between the two, judged by its timestamp and not by when it arrives (a frame in
  // flight as the scan ends was exposed while the lasers were on); every frame is dark once
  // the supervisor tripped.
  std::atomic<int64_t> lasers_on_since_ns_{0};
  std::atomic<int64_t> lasers_off_since_ns_{0};
  std::vector<std::unique_ptr<std::atomic<int64_t>>> first_frame_ns_;
  std::atomic<bool> capture_busy_{false};

  // The pipeline of one scan.
  std::unique_ptr<BoundedQueue<CapturedItem>> capture_queue_;
  std::unique_ptr<BoundedQueue<FrameRecord>> record_queue_;
  std::vector<std::thread> workers_;
  std::thread writer_;
  std::atomic<bool> store_failed_{false};
  std::atomic<uint64_t> peaks_{0};

  std::atomic<int64_t> loop_heartbeat_ns_{0};
  std::thread loop_;
};

}  // namespace mirrorscan::scan

#include "firmware/scan/sequencer.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <sstream>

#include <spdlog/spdlog.h>

#include "common/protocol/sha256.h"
#include "firmware/hal/clock.h"

namespace mirrorscan::scan {
namespace {

constexpr int64_t kMs = 1000000;
// After a move command, how long a still slide away from its target is given before it
// counts as stopped short.
constexpr int64_t kStillGraceNs = 200 * kMs;

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

// The SHA-256 of data_dir/calibration.json, as the device API's status reports it (one
// identifier for "which calibration"); null when there is none.
nlohmann::json CalibrationSha256(const std::filesystem::path& data_dir) {
  const std::filesystem::path file = data_dir / "calibration.json";
  if (data_dir.empty() || !std::filesystem::exists(file)) return nullptr;
  return protocol::Sha256::HexOfFile(file);
}

std::string_view FooterStatus(SequencerState end) {
  return end == SequencerState::kDone      ? "complete"
         : end == SequencerState::kAborted ? "aborted"
                                           : "fault";
}

}  // namespace

Sequencer::Sequencer(SequencerDevices devices, store::ScanStore& store, SequencerOptions options)
    : devices_(std::move(devices)), store_(store), options_(std::move(options)) {
  monitor_ = std::make_unique<DriveMonitor>(*devices_.drive, options_.drive_poll);
  supervisor_ = std::make_unique<SafetySupervisor>(*devices_.lasers, *devices_.drive, *monitor_,
                                                   options_.supervisor, [this](const Trip& trip) {
                                                     Command command;
                                                     command.type = Command::Type::kTrip;
                                                     command.trip = trip;
                                                     Post(std::move(command));
                                                   });
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    counters_.push_back(std::make_unique<CameraCounters>());
    first_frame_ns_.push_back(std::make_unique<std::atomic<int64_t>>(0));
  }
  status_.updated_ns = hal::SteadyNowNs();
  loop_ = std::thread([this] { Loop(); });
  if (devices_.button != nullptr) {
    try {
      devices_.button->Start([this](const hal::ButtonEvent& event) {
        if (event.type != hal::ButtonEvent::Type::kPressed) return;
        // A press during a scan aborts it straight through the supervisor (no hop via the
        // control loop); otherwise it starts one.
        if (ScanRunning()) {
          supervisor_->RequestTrip(false, "button pressed during the scan");
        } else {
          Command command;
          command.type = Command::Type::kButton;
          Post(std::move(command));
        }
      });
    } catch (...) {
      {
        std::lock_guard lock(command_mutex_);
        stop_ = true;
      }
      command_ready_.notify_all();
      loop_.join();
      throw;
    }
  }
}

Sequencer::~Sequencer() {
  if (devices_.button != nullptr) devices_.button->Stop();
  {
    std::lock_guard lock(command_mutex_);
    stop_ = true;
  }
  command_ready_.notify_all();
  loop_.join();
  supervisor_.reset();
  monitor_.reset();
  devices_.lasers->SafeOff();
}

void Sequencer::Post(Command command) {
  {
    std::lock_guard lock(command_mutex_);
    commands_.push_back(std::move(command));
  }
  command_ready_.notify_all();
}

bool Sequencer::ScanRunning() const {
  std::lock_guard lock(status_mutex_);
  switch (status_.state) {
    case SequencerState::kHoming:
    case SequencerState::kArming:
    case SequencerState::kSweeping:
    case SequencerState::kFinishing:
      return true;
    default:
      return false;
  }
}

std::string Sequencer::StartScan(std::string_view origin) {
  if (capture_busy_ || ScanRunning()) {
    throw ScanControlError(ScanControlError::Kind::kBusy, "a scan or capture is running");
  }
  Command command;
  command.type = Command::Type::kStart;
  command.origin = std::string(origin);
  command.reply = std::make_shared<std::promise<std::string>>();
  std::future<std::string> id = command.reply->get_future();
  Post(std::move(command));
  return id.get();
}

void Sequencer::Abort(std::string_view reason) {
  if (ScanRunning()) supervisor_->RequestTrip(false, std::string(reason));
}

ScanStatus Sequencer::Status() const {
  std::lock_guard lock(status_mutex_);
  return status_;
}

bool Sequencer::Alive(int64_t max_age_ns) const {
  const int64_t now_ns = hal::SteadyNowNs();
  return now_ns - loop_heartbeat_ns_.load() <= max_age_ns &&
         now_ns - supervisor_->heartbeat_ns() <= max_age_ns;
}

std::optional<Trip> Sequencer::last_trip() const {
  std::lock_guard lock(status_mutex_);
  return last_trip_;
}

int Sequencer::Subscribe(Listener listener) {
  std::lock_guard lock(listeners_mutex_);
  const int handle = next_listener_++;
  listeners_[handle] = std::move(listener);
  return handle;
}

void Sequencer::Unsubscribe(int handle) {
  std::lock_guard lock(listeners_mutex_);
  listeners_.erase(handle);
}

void Sequencer::Emit(ScanEvent::Type type) {
  ScanEvent event;
  event.type = type;
  event.status = Status();
  std::lock_guard lock(listeners_mutex_);
  for (auto& [handle, listener] : listeners_) {
    try {
      listener(event);
    } catch (const std::exception& e) {
      spdlog::error("sequencer: event listener {} threw: {}", handle, e.what());
    }
  }
}

void Sequencer::SetState(SequencerState state, const std::string& reason) {
  {
    std::lock_guard lock(status_mutex_);
    status_.state = state;
    status_.reason = reason;
    status_.updated_ns = hal::SteadyNowNs();
  }
  state_since_ns_ = hal::SteadyNowNs();
  if (reason.empty()) {
    spdlog::info("sequencer: {}", SequencerStateName(state));
  } else {
    spdlog::info("sequencer: {} ({})", SequencerStateName(state), reason);
  }
  Emit(ScanEvent::Type::kState);
}

void Sequencer::Loop() {
  while (true) {
    std::deque<Command> commands;
    bool stopping = false;
    {
      std::unique_lock lock(command_mutex_);
      command_ready_.wait_for(lock, options_.tick, [&] { return stop_ || !commands_.empty(); });
      commands.swap(commands_);
      stopping = stop_;
    }
    for (Command& command : commands) {
      try {
        Handle(command);
      } catch (const std::exception& e) {
        // Nothing may escape the loop with the lasers on.
        if (ScanRunning()) Fail(std::string("internal error: ") + e.what());
      }
    }
    if (stopping) break;
    loop_heartbeat_ns_ = hal::SteadyNowNs();
    if (devices_.interlock != nullptr) devices_.interlock->Kick();
    try {
      Step();
    } catch (const std::exception& e) {
      if (ScanRunning()) Fail(std::string("internal error: ") + e.what());
    }
  }
  if (ScanRunning()) Fail("firmware stopping");
}

void Sequencer::Handle(Command& command) {
  switch (command.type) {
    case Command::Type::kStart:
      if (ScanRunning() || capture_busy_) {
        command.reply->set_exception(std::make_exception_ptr(
            ScanControlError(ScanControlError::Kind::kBusy, "a scan or capture is running")));
        return;
      }
      BeginScan(command.origin, command.reply);
      return;
    case Command::Type::kButton:
      if (ScanRunning()) {
        supervisor_->RequestTrip(false, "button pressed during the scan");
      } else if (!capture_busy_) {
        BeginScan("button", nullptr);
      }
      return;
    case Command::Type::kTrip:
      if (!ScanRunning()) return;  // already ended (e.g. a second cause of the same fault)
      {
        std::lock_guard lock(status_mutex_);
        last_trip_ = command.trip;
      }
      EndScan(command.trip.fault ? SequencerState::kFault : SequencerState::kAborted,
              command.trip.reason);
      return;
  }
}

nlohmann::json Sequencer::Header(const std::string& origin) const {
  nlohmann::json cameras = nlohmann::json::array();
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    const hal::CameraConfig& c = devices_.cameras[i].camera->config();
    cameras.push_back({{"index", i},
                       {"name", devices_.cameras[i].name},
                       {"width", c.width},
                       {"height", c.height},
                       {"fps", c.fps},
                       {"exposure_us", c.exposure_us},
                       {"gain", c.gain}});
  }
  return {{"device", options_.device},
          {"board", options_.board},
          {"firmware_version", options_.firmware_version},
          {"calibration_sha256", CalibrationSha256(options_.data_dir)},
          {"cameras", cameras},
          {"lasers", {{"count", devices_.lasers->count()}}},
          {"slide",
           {{"speed_mm_s", options_.speed_mm_s},
            {"sweep_start_mm", options_.sweep_start_mm},
            {"sweep_end_mm", options_.sweep_end_mm}}},
          {"start_time", UtcNow()},
          {"start_steady_ns", hal::SteadyNowNs()},
          {"origin", origin},
          {"position_source", "drive readback polled every " +
                                  std::to_string(options_.drive_poll.count() / kMs) +
                                  " ms, interpolated to the exposure time"}};
}

nlohmann::json Sequencer::Footer(SequencerState end, const std::string& reason) const {
  nlohmann::json frames = nlohmann::json::array();
  nlohmann::json camera_dropped = nlohmann::json::array();
  nlohmann::json queue_dropped = nlohmann::json::array();
  uint64_t dropped = 0;
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    const CameraCounters& c = *counters_[i];
    const uint64_t by_camera = devices_.cameras[i].camera->dropped() - c.camera_dropped_at_start;
    frames.push_back(c.stored.load());
    camera_dropped.push_back(by_camera);
    queue_dropped.push_back(c.queue_dropped.load());
    dropped += by_camera + c.queue_dropped.load();
  }
  return {{"status", FooterStatus(end)},
          {"reason", reason},
          {"end_time", UtcNow()},
          {"frames", frames},
          {"camera_dropped", camera_dropped},
          {"queue_dropped", queue_dropped},
          {"dropped", dropped},
          {"peaks", peaks_.load()}};
}

void Sequencer::BeginScan(const std::string& origin,
                          const std::shared_ptr<std::promise<std::string>>& reply) {
  for (size_t i = 0; i < counters_.size(); ++i) {
    counters_[i]->stored = 0;
    counters_[i]->queue_dropped = 0;
    counters_[i]->camera_dropped_at_start = 0;
    *first_frame_ns_[i] = 0;
  }
  peaks_ = 0;
  store_failed_ = false;
  supervisor_->Disarm();  // forget a trip that raced with the end of the last scan
  try {
    handle_ = store_.BeginScan(Header(origin));
  } catch (const std::exception& e) {
    spdlog::error("sequencer: cannot begin a scan: {}", e.what());
    if (reply) {
      reply->set_exception(std::make_exception_ptr(ScanControlError(
          ScanControlError::Kind::kUnavailable, std::string("scan store: ") + e.what())));
    }
    {
      std::lock_guard lock(status_mutex_);
      status_.scan_id.clear();
    }
    SetState(SequencerState::kFault, std::string("scan store: ") + e.what());
    return;
  }
  {
    std::lock_guard lock(status_mutex_);
    status_ = ScanStatus{};
    status_.scan_id = handle_->id();
  }
  if (reply) reply->set_value(handle_->id());
  spdlog::info("sequencer: scan {} started by {}", handle_->id(), origin);
  try {
    devices_.led->Set(hal::LedPattern::kBlinkSlow);
  } catch (const std::exception& e) {
    spdlog::warn("sequencer: led: {}", e.what());
  }
  SetState(SequencerState::kHoming);
  try {
    if (devices_.drive->Status().fault) devices_.drive->ResetFault();
    devices_.drive->Enable(true);
    devices_.drive->StartHome();
    monitor_->SetTarget(std::nullopt);
  } catch (const std::exception& e) {
    Fail(std::string("drive: ") + e.what());
    return;
  }
  command_ns_ = hal::SteadyNowNs();
  positioning_ = false;
}

void Sequencer::Step() {
  SequencerState state;
  {
    std::lock_guard lock(status_mutex_);
    state = status_.state;
  }
  if (state != SequencerState::kHoming && state != SequencerState::kArming &&
      state != SequencerState::kSweeping) {
    return;
  }
  if (supervisor_->tripped()) return;  // its report is on the way
  const int64_t now_ns = hal::SteadyNowNs();
  const int64_t stale_ns = options_.supervisor.drive_stale.count();
  if (now_ns - std::max(monitor_->last_good_ns(), command_ns_) > stale_ns) {
    // While sweeping the supervisor trips on this too; before that only the loop watches.
    Fail(monitor_->NotAnswering(now_ns));
    return;
  }
  if (state == SequencerState::kArming) {
    StepArming();
    return;
  }
  const std::optional<DriveSample> sample = monitor_->Latest();
  if (state == SequencerState::kHoming) {
    if (now_ns - state_since_ns_ > static_cast<int64_t>(options_.home_timeout_s * 1e9)) {
      Fail("homing did not finish within home_timeout_s");
      return;
    }
    if (sample && sample->request_ns > command_ns_) StepHoming(*sample);
    return;
  }
  const double sweep_s =
      std::abs(options_.sweep_end_mm - options_.sweep_start_mm) / options_.speed_mm_s;
  if (now_ns - state_since_ns_ > static_cast<int64_t>((sweep_s * 1.5 + 5.0) * 1e9)) {
    Fail("the sweep did not finish in time");
    return;
  }
  if (sample && sample->request_ns > command_ns_) StepSweeping(*sample);
}

void Sequencer::StepHoming(const DriveSample& sample) {
  const hal::SlideStatus& s = sample.status;
  if (s.fault) {
    Fail("drive fault " + std::to_string(s.fault_code) + " while homing");
    return;
  }
  if (s.moving || !s.homed) return;
  const double off_start = std::abs(sample.position_mm - options_.sweep_start_mm);
  if (off_start > options_.at_target_tolerance_mm) {
    if (positioning_ && hal::SteadyNowNs() - command_ns_ > kStillGraceNs) {
      Fail("the slide stopped at " + std::to_string(sample.position_mm) +
           " mm, not at the sweep start");
      return;
    }
    if (!positioning_) {
      devices_.drive->SetSpeed(options_.speed_mm_s);
      devices_.drive->Start(options_.sweep_start_mm);
      command_ns_ = hal::SteadyNowNs();
      positioning_ = true;
    }
    return;
  }
  // At the start: cameras on, then wait for every camera's first frame (arming).
  StartPipeline();
  SetState(SequencerState::kArming);
}

void Sequencer::StartPipeline() {
  size_t buffers = 0;
  for (const auto& c : devices_.cameras) buffers += c.camera->config().buffer_count;
  capture_queue_ = std::make_unique<BoundedQueue<CapturedItem>>(buffers);
  record_queue_ = std::make_unique<BoundedQueue<FrameRecord>>(options_.record_queue_capacity);
  for (int i = 0; i < options_.peak_workers; ++i) workers_.emplace_back([this] { WorkerLoop(); });
  writer_ = std::thread([this] { WriterLoop(); });
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    const std::string name = devices_.cameras[i].name;
    devices_.cameras[i].camera->Start(
        [this, i](hal::Frame frame) { OnFrame(static_cast<int>(i), std::move(frame)); },
        [this, name](const hal::HardwareError* error) {
          supervisor_->RequestTrip(
              true, "camera " + name + ": " + (error ? error->what() : "stream ended"));
        });
  }
}

void Sequencer::StepArming() {
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    if (first_frame_ns_[i]->load() == 0) {
      if (hal::SteadyNowNs() - state_since_ns_ > options_.first_frame_timeout.count()) {
        Fail("camera " + devices_.cameras[i].name + " delivered no frame");
      }
      return;
    }
  }
  std::vector<SafetySupervisor::WatchedCamera> watched;
  for (size_t i = 0; i < devices_.cameras.size(); ++i) {
    watched.push_back({devices_.cameras[i].name, devices_.cameras[i].camera});
    counters_[i]->camera_dropped_at_start = devices_.cameras[i].camera->dropped();
  }
  supervisor_->Arm(watched, true);
  lasers_on_since_ns_ = 0;  // the last sweep's times must not make this one's first frames lit
  lasers_off_since_ns_ = 0;
  recording_ = true;
  devices_.lasers->SetAll(true);
  lasers_on_since_ns_ = hal::SteadyNowNs();
  devices_.drive->SetSpeed(options_.speed_mm_s);
  devices_.drive->Start(options_.sweep_end_mm);
  monitor_->SetTarget(options_.sweep_end_mm);
  command_ns_ = hal::SteadyNowNs();
  last_progress_ns_ = 0;
  try {
    devices_.led->Set(hal::LedPattern::kBlinkFast);
  } catch (const std::exception& e) {
    spdlog::warn("sequencer: led: {}", e.what());
  }
  SetState(SequencerState::kSweeping);
}

void Sequencer::StepSweeping(const DriveSample& sample) {
  const double span = options_.sweep_end_mm - options_.sweep_start_mm;
  const double progress =
      std::clamp((sample.position_mm - options_.sweep_start_mm) / span, 0.0, 1.0);
  {
    std::lock_guard lock(status_mutex_);
    status_.progress = progress;
    status_.position_mm = sample.position_mm;
    status_.frames = 0;
    status_.dropped = 0;
    for (size_t i = 0; i < counters_.size(); ++i) {
      status_.frames += counters_[i]->stored;
      status_.dropped += counters_[i]->queue_dropped + devices_.cameras[i].camera->dropped() -
                         counters_[i]->camera_dropped_at_start;
    }
    status_.peaks = peaks_;
    status_.updated_ns = hal::SteadyNowNs();
  }
  if (sample.time_ns - last_progress_ns_ >
      static_cast<int64_t>(options_.progress_interval_s * 1e9)) {
    last_progress_ns_ = sample.time_ns;
    Emit(ScanEvent::Type::kProgress);
  }
  if (sample.status.moving) return;
  if (std::abs(sample.position_mm - options_.sweep_end_mm) <= options_.at_target_tolerance_mm) {
    EndScan(SequencerState::kDone, "");
  } else if (hal::SteadyNowNs() - command_ns_ > kStillGraceNs && !sample.status.fault) {
    // (A drive fault is the supervisor's to report, with its code.)
    Fail("the slide stopped at " + std::to_string(sample.position_mm) + " mm before the sweep end");
  }
}

void Sequencer::OnFrame(int camera, hal::Frame frame) {
  const int64_t now_ns = hal::SteadyNowNs();
  supervisor_->CameraFrame(camera);
  int64_t expected = 0;
  first_frame_ns_[camera]->compare_exchange_strong(expected, now_ns);
  if (!recording_) return;  // before the sweep: the frame goes back to the pool
  CapturedItem item;
  item.camera = camera;
  // Lit: the control loop had switched the lasers on before the exposure began, and no
  // trip has made them safe since (the supervisor flags the trip before it drives the
  // lines off). The sequencer's own record, not a query of the laser bank per frame.
  const int64_t lasers_on_since_ns = lasers_on_since_ns_.load();
  const int64_t lasers_off_since_ns = lasers_off_since_ns_.load();
  item.lasers_on = lasers_on_since_ns != 0 && frame.timestamp_ns() >= lasers_on_since_ns &&
                   (lasers_off_since_ns == 0 || frame.timestamp_ns() < lasers_off_since_ns) &&
                   !supervisor_->tripped();
  item.frame = std::move(frame);
  if (!capture_queue_->TryPush(item)) ++counters_[camera]->queue_dropped;
}

void Sequencer::WorkerLoop() {
  PeakExtractor extractor;
  while (std::optional<CapturedItem> item = capture_queue_->Pop()) {
    FrameRecord record;
    record.camera = static_cast<uint8_t>(item->camera);
    record.lasers_on = item->lasers_on;
    record.sequence = static_cast<uint32_t>(item->frame.sequence());
    record.timestamp_ns = item->frame.timestamp_ns();
    record.slide_position_mm = monitor_->PositionAt(record.timestamp_ns);
    try {
      extractor.Extract(item->frame.view(), options_.peaks, &record.peaks);
    } catch (const std::exception& e) {
      supervisor_->RequestTrip(true, std::string("peak extraction: ") + e.what());
      continue;
    }
    item->frame.Release();
    if (!record_queue_->TryPush(record)) ++counters_[item->camera]->queue_dropped;
  }
}

void Sequencer::WriterLoop() {
  while (std::optional<FrameRecord> record = record_queue_->Pop()) {
    if (store_failed_) continue;  // the scan is ending with the store's fault
    try {
      handle_->AppendFrame(*record);
      ++counters_[record->camera]->stored;
      peaks_ += record->peaks.size();
    } catch (const std::exception& e) {
      store_failed_ = true;
      supervisor_->RequestTrip(true, std::string("scan store: ") + e.what());
    }
  }
}

void Sequencer::StopCameras() {
  for (auto& c : devices_.cameras) c.camera->Stop();
}

void Sequencer::Fail(const std::string& reason) {
  Trip trip;
  trip.fault = true;
  trip.reason = reason;
  trip.detected_ns = hal::SteadyNowNs();
  // Dark in the records from here on, before Disarm() clears the supervisor's trip flag.
  lasers_off_since_ns_ = hal::SteadyNowNs();
  supervisor_->Disarm();
  devices_.lasers->SafeOff();
  trip.safe_ns = hal::SteadyNowNs();
  try {
    devices_.drive->Stop();
  } catch (const std::exception& e) {
    spdlog::error("sequencer: drive stop failed: {}", e.what());
  }
  {
    std::lock_guard lock(status_mutex_);
    last_trip_ = trip;
  }
  EndScan(SequencerState::kFault, reason);
}

void Sequencer::EndScan(SequencerState end, const std::string& reason) {
  recording_ = false;
  lasers_off_since_ns_ = hal::SteadyNowNs();  // as in Fail(): before Disarm() clears the trip flag
  supervisor_->Disarm();
  if (!devices_.lasers->SafeOff()) spdlog::critical("sequencer: a laser line did not go off");
  if (end != SequencerState::kDone) {
    try {
      devices_.drive->Stop();
    } catch (const std::exception& e) {
      spdlog::error("sequencer: drive stop failed: {}", e.what());
    }
  }
  SetState(SequencerState::kFinishing, reason);
  StopCameras();
  if (capture_queue_) capture_queue_->Close();
  for (std::thread& worker : workers_) worker.join();
  workers_.clear();
  if (record_queue_) record_queue_->Close();
  if (writer_.joinable()) writer_.join();
  capture_queue_.reset();
  record_queue_.reset();

  SequencerState final_state = end;
  std::string final_reason = reason;
  if (handle_) {
    const nlohmann::json footer = Footer(end, reason);
    if (!store_failed_) {
      try {
        handle_->Finish(footer);
      } catch (const std::exception& e) {
        final_state = SequencerState::kFault;
        final_reason = std::string("scan store: ") + e.what();
      }
    }
    spdlog::info("sequencer: scan {} {}: {}", handle_->id(), FooterStatus(end), footer.dump());
    handle_.reset();  // a failed handle is kept as "partial" with its readable prefix
  }
  {
    std::lock_guard lock(status_mutex_);
    status_.frames = 0;
    status_.dropped = 0;
    for (size_t i = 0; i < counters_.size(); ++i) {
      status_.frames += counters_[i]->stored;
      status_.dropped += counters_[i]->queue_dropped + devices_.cameras[i].camera->dropped() -
                         counters_[i]->camera_dropped_at_start;
    }
    status_.peaks = peaks_;
    if (final_state == SequencerState::kDone) status_.progress = 1.0;
  }
  try {
    devices_.led->Set(final_state == SequencerState::kDone    ? hal::LedPattern::kOn
                      : final_state == SequencerState::kFault ? hal::LedPattern::kFault
                                                              : hal::LedPattern::kOff);
  } catch (const std::exception& e) {
    spdlog::warn("sequencer: led: {}", e.what());
  }
  SetState(final_state, final_reason);
}

CapturedFrame Sequencer::Capture(const std::string& camera, bool lasers_on) {
  auto it = std::find_if(devices_.cameras.begin(), devices_.cameras.end(),
                         [&](const auto& c) { return c.name == camera; });
  if (it == devices_.cameras.end()) {
    throw ScanControlError(ScanControlError::Kind::kInvalidArgument,
                           "no camera named \"" + camera + "\"");
  }
  if (capture_busy_.exchange(true)) {
    throw ScanControlError(ScanControlError::Kind::kBusy, "a capture is running");
  }
  struct Release {
    std::atomic<bool>& busy;
    ~Release() { busy = false; }
  } release{capture_busy_};
  if (ScanRunning()) throw ScanControlError(ScanControlError::Kind::kBusy, "a scan is running");

  hal::Camera& cam = *it->camera;
  std::mutex mutex;
  std::condition_variable ready;
  CapturedFrame captured;
  bool got = false;
  std::atomic<int64_t> lasers_set_ns{INT64_MAX};
  try {
    if (lasers_on) {
      supervisor_->Arm({}, false);  // the on-time limit still applies
      devices_.lasers->SetAll(true);
    }
    lasers_set_ns = hal::SteadyNowNs();
    cam.Start([&](hal::Frame frame) {
      // Only a frame exposed after the lasers were switched shows their state.
      if (frame.timestamp_ns() < lasers_set_ns.load()) return;
      std::lock_guard lock(mutex);
      if (got) return;
      const ImageView view = frame.view();
      captured.pixels.resize(static_cast<size_t>(view.width) * view.height);
      for (int row = 0; row < view.height; ++row) {
        std::copy_n(view.data + row * view.stride, view.width,
                    captured.pixels.data() + static_cast<size_t>(row) * view.width);
      }
      captured.width = view.width;
      captured.height = view.height;
      captured.timestamp_ns = frame.timestamp_ns();
      got = true;
      ready.notify_all();
    });
    std::unique_lock lock(mutex);
    ready.wait_for(lock, options_.first_frame_timeout, [&] { return got; });
  } catch (const std::exception& e) {
    cam.Stop();
    supervisor_->Disarm();
    devices_.lasers->SafeOff();
    throw ScanControlError(ScanControlError::Kind::kUnavailable,
                           "capture from " + camera + ": " + e.what());
  }
  cam.Stop();
  supervisor_->Disarm();
  devices_.lasers->SafeOff();
  if (!got) {
    throw ScanControlError(ScanControlError::Kind::kUnavailable,
                           "camera " + camera + " delivered no frame");
  }
  captured.camera = camera;
  captured.lasers_on = lasers_on;
  return captured;
}

}  // namespace mirrorscan::scan

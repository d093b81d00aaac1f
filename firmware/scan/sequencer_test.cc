// The sequencer on the virtual board's hardware minus the renderer: the simulated Modbus
// drive over loopback TCP through the real ModbusSlideDrive, virtual GPIO lines, and
// replay cameras playing PGM frames this test writes (a horizontal stripe at a known row),
// so it runs under qemu-aarch64 too. Every fault test asserts the laser lines' levels,
// the trip time, the final state, and the archive's footer and metadata in the store.

#include "firmware/scan/sequencer.h"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "boards/virtual/drive_sim/drive_sim.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "firmware/board/gpio_factory.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/modbus/modbus_slide_drive.h"
#include "firmware/hal/replay/replay_camera.h"
#include "firmware/hal/virtual/virtual_gpio_line.h"
#include "firmware/hal/virtual/virtual_monostable.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan::scan {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr int kFiles = 8;
constexpr double kSweepStart = 20.0;
constexpr double kSweepEnd = 170.0;
constexpr double kSpeed = 150.0;  // a 1 s sweep
constexpr int64_t kMs = 1000000;

double StripeRow(uint64_t sequence) { return 30.0 + 5.0 * static_cast<double>(sequence % kFiles); }

// A camera decorator that injects what the replay camera cannot: a stalled sensor (frames
// vanish without a trace) and lost frames (a sequence gap, counted in dropped()).
class FaultyCamera final : public hal::Camera {
 public:
  explicit FaultyCamera(std::unique_ptr<hal::Camera> inner) : inner_(std::move(inner)) {}
  void Configure(const hal::CameraConfig& config) override { inner_->Configure(config); }
  void Start(FrameCallback on_frame, EndCallback on_end) override {
    injected_ = 0;
    {
      std::lock_guard lock(mutex_);
      delivered_.clear();
    }
    inner_->Start(
        [this, on_frame](hal::Frame frame) {
          if (stalled_) return;
          const int n = drop_every_;
          if (n > 0 && (frame.sequence() + 1) % n == 0) {
            ++injected_;
            return;
          }
          {
            std::lock_guard lock(mutex_);
            delivered_.push_back(frame.sequence());
          }
          on_frame(std::move(frame));
        },
        std::move(on_end));
  }
  void Stop() override { inner_->Stop(); }
  int64_t clock_ns() const override { return inner_->clock_ns(); }
  bool streaming() const override { return inner_->streaming(); }
  uint64_t dropped() const override { return inner_->dropped() + injected_; }
  const hal::CameraConfig& config() const override { return inner_->config(); }

  void SetStalled(bool stalled) { stalled_ = stalled; }
  void SetDropEveryNth(int n) { drop_every_ = n; }
  // The sequence numbers of the frames handed to the consumer since Start().
  std::vector<uint64_t> Delivered() const {
    std::lock_guard lock(mutex_);
    return delivered_;
  }

 private:
  std::unique_ptr<hal::Camera> inner_;
  mutable std::mutex mutex_;
  std::vector<uint64_t> delivered_;
  std::atomic<bool> stalled_{false};
  std::atomic<int> drop_every_{0};
  std::atomic<uint64_t> injected_{0};
};

// A camera whose every frame costs the host `work` to make, as the virtual cabinet's
// renderer does on a loaded machine: the stripe of StripeRow(sequence), late.
class SlowRenderCamera final : public hal::ThreadedCamera {
 public:
  explicit SlowRenderCamera(milliseconds work) : work_(work) {}
  ~SlowRenderCamera() override { Stop(); }

 protected:
  Produced Produce(uint64_t sequence, int64_t, uint8_t* pixels) override {
    std::this_thread::sleep_for(work_);
    for (int v = 0; v < kHeight; ++v) {
      const double d = (v - StripeRow(sequence)) / 1.2;
      std::fill_n(pixels + v * kWidth, kWidth,
                  static_cast<uint8_t>(std::lround(20.0 + 180.0 * std::exp(-0.5 * d * d))));
    }
    return Produced::kFrame;
  }

 private:
  const milliseconds work_;
};

bool Eventually(const std::function<bool()>& condition, milliseconds deadline = seconds(15)) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(milliseconds(1));
  }
  return true;
}

class SequencerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const fs::path frames = dir_ / "frames";
    fs::create_directories(frames);
    for (int k = 0; k < kFiles; ++k) {
      std::vector<uint8_t> pixels(kWidth * kHeight);
      for (int v = 0; v < kHeight; ++v) {
        const double d = (v - StripeRow(k)) / 1.2;
        const auto level = static_cast<uint8_t>(std::lround(20.0 + 180.0 * std::exp(-0.5 * d * d)));
        std::fill_n(pixels.begin() + v * kWidth, kWidth, level);
      }
      char name[32];
      std::snprintf(name, sizeof name, "%03d.pgm", k);
      hal::WritePgm(frames / name, kWidth, kHeight, pixels.data());
    }

    sim_ = virtual_cabinet::DriveSim::ServeTcp({});
    hal::ModbusDriveConfig modbus;
    modbus.host = "127.0.0.1";
    modbus.port = sim_->port();
    drive_ = std::make_unique<hal::ModbusSlideDrive>(modbus);

    hal::GpioConfig gpio;
    gpio.backend = hal::GpioBackend::kVirtual;
    gpio.lasers = {{17, false}, {27, false}, {22, false}};
    gpio.led = {23, false};
    gpio.button = {24, true};
    gpio.debounce_ms = 5;
    board::GpioLines lines = board::MakeGpioLines(gpio, hal::GpioBackend::kVirtual);
    for (auto& laser : lines.lasers) {
      laser_lines_.push_back(dynamic_cast<hal::VirtualGpioLine*>(laser.line.get()));
    }
    button_line_ = dynamic_cast<hal::VirtualGpioLine*>(lines.button.line.get());
    interlock_ = dynamic_cast<hal::VirtualMonostable*>(lines.interlock.line.get());
    gpio_ = board::MakeGpioDevices(gpio, std::move(lines));

    for (int i = 0; i < 2; ++i) {
      auto camera = std::make_unique<FaultyCamera>(
          std::make_unique<hal::ReplayCamera>(hal::ReplayOptions{frames, true}));
      hal::CameraConfig config;
      config.width = kWidth;
      config.height = kHeight;
      config.fps = 30;
      config.exposure_us = 5000;
      camera->Configure(config);
      cameras_.push_back(std::move(camera));
    }
    store_ = store::ScanStore::Open(dir_ / "data");

    options_.board = "test";
    options_.device = "test-device";
    options_.firmware_version = "0.0-test";
    options_.data_dir = dir_ / "data";
    options_.sweep_start_mm = kSweepStart;
    options_.sweep_end_mm = kSweepEnd;
    options_.speed_mm_s = kSpeed;
    options_.home_timeout_s = 5;
    options_.supervisor.max_laser_on_s = 5;
  }

  void TearDown() override {
    sequencer_.reset();
    sim_->SetResponding(true);
    cameras_.clear();
    gpio_ = {};
    drive_.reset();
    sim_.reset();
    store_.reset();
  }

  void MakeSequencer() {
    SequencerDevices devices;
    devices.cameras = {{"upper", cameras_[0].get()}, {"lower", cameras_[1].get()}};
    devices.lasers = gpio_.lasers.get();
    devices.interlock = gpio_.interlock.get();
    devices.led = gpio_.led.get();
    devices.button = gpio_.button.get();
    devices.drive = drive_.get();
    sequencer_ = std::make_unique<Sequencer>(devices, *store_, options_);
    sequencer_->Subscribe([this](const ScanEvent& event) {
      std::lock_guard lock(events_mutex_);
      events_.push_back(event);
    });
  }

  bool WaitState(SequencerState state, milliseconds deadline = seconds(15)) {
    return Eventually([&] { return sequencer_->Status().state == state; }, deadline);
  }
  // Sweeping with the slide at least `mm` past the start.
  bool WaitSweptPast(double mm) {
    return Eventually([&] {
      const ScanStatus s = sequencer_->Status();
      return s.state == SequencerState::kSweeping && s.position_mm > kSweepStart + mm;
    });
  }
  hal::VirtualMonostable* interlock_ = nullptr;
  bool LasersLow() const {
    for (const auto* line : laser_lines_) {
      if (line->driven()) return false;
    }
    return true;
  }
  bool LasersWereOn() const {
    for (const auto* line : laser_lines_) {
      const std::vector<bool> h = line->history();
      if (std::find(h.begin(), h.end(), true) == h.end()) return false;
    }
    return true;
  }
  int64_t LasersOffNs() const {
    int64_t last = 0;
    for (const auto* line : laser_lines_) last = std::max(last, line->last_change_ns());
    return last;
  }
  void PressButton() {
    // Active-low: pressed pulls the line low; held 30 ms, then released. The level before
    // must have been stable for the debounce time, or the press counts as bounce.
    std::this_thread::sleep_for(milliseconds(20));
    button_line_->InjectEdge(hal::SteadyNowNs(), false);
    std::this_thread::sleep_for(milliseconds(30));
    button_line_->InjectEdge(hal::SteadyNowNs(), true);
  }
  std::vector<SequencerState> States() {
    std::lock_guard lock(events_mutex_);
    std::vector<SequencerState> states;
    for (const ScanEvent& e : events_) {
      if (e.type == ScanEvent::Type::kState) states.push_back(e.status.state);
    }
    return states;
  }
  // The archive's footer and the store's metadata agree on how the scan ended.
  ScanArchive ExpectStored(const std::string& id, store::ScanState state,
                           const std::string& footer_status) {
    const store::ScanInfo info = store_->Get(id);
    EXPECT_EQ(info.state, state) << store::ScanStateName(info.state) << ": " << info.reason;
    ScanArchive archive = ReadScanFile(store_->Path(id));
    EXPECT_EQ(archive.header.value("scan_id", ""), id);
    if (!footer_status.empty()) {
      EXPECT_TRUE(archive.report.complete) << archive.report.message;
      EXPECT_TRUE(archive.footer.has_value());
      if (archive.footer) {
        EXPECT_EQ((*archive.footer)["status"], footer_status);
      }
    }
    return archive;
  }

  // A scan finished before a fault, and what must survive of it.
  struct FinishedScan {
    std::string id;
    std::string sha256;  // of its archive file
    size_t frames = 0;
  };
  FinishedScan ScanToTheEnd() {
    FinishedScan scan;
    scan.id = sequencer_->StartScan("test");
    EXPECT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
    scan.sha256 = protocol::Sha256::HexOfFile(store_->Path(scan.id));
    scan.frames = ReadScanFile(store_->Path(scan.id)).frames.size();
    EXPECT_GT(scan.frames, 0u);
    return scan;
  }
  // Byte for byte what it was, still listed as complete.
  void ExpectIntact(const FinishedScan& scan) {
    const ScanArchive archive = ExpectStored(scan.id, store::ScanState::kComplete, "complete");
    EXPECT_EQ(archive.frames.size(), scan.frames);
    EXPECT_EQ(protocol::Sha256::HexOfFile(store_->Path(scan.id)), scan.sha256);
    EXPECT_EQ(store_->Get(scan.id).frames, scan.frames);
  }

  const test_support::TempDir dir_{"sequencer_test"};
  std::unique_ptr<virtual_cabinet::DriveSim> sim_;
  std::unique_ptr<hal::ModbusSlideDrive> drive_;
  std::vector<hal::VirtualGpioLine*> laser_lines_;
  hal::VirtualGpioLine* button_line_ = nullptr;
  board::GpioDevices gpio_;
  std::vector<std::unique_ptr<FaultyCamera>> cameras_;
  std::unique_ptr<store::ScanStore> store_;
  SequencerOptions options_;
  std::unique_ptr<Sequencer> sequencer_;
  std::mutex events_mutex_;
  std::vector<ScanEvent> events_;
};

// The archive names the calibration it was taken with by the same SHA-256 the device API
// reports for the stored calibration.json.
TEST_F(SequencerTest, HeaderNamesTheStoredCalibrationBySha256) {
  fs::create_directories(dir_ / "data");
  const fs::path calibration = dir_ / "data" / "calibration.json";
  std::ofstream(calibration) << R"({"schema": "mirrorscan.calibration"})";
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
  const ScanArchive archive = ExpectStored(id, store::ScanState::kComplete, "complete");
  EXPECT_EQ(archive.header["calibration_sha256"], protocol::Sha256::HexOfFile(calibration));
}

TEST_F(SequencerTest, CompleteScanStoresEveryFramesPeaks) {
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  EXPECT_TRUE(store::IsValidScanId(id));
  ASSERT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
  EXPECT_TRUE(LasersLow());
  EXPECT_TRUE(LasersWereOn());
  EXPECT_EQ(sequencer_->Status().scan_id, id);
  EXPECT_EQ(sequencer_->Status().dropped, 0u);

  const ScanArchive archive = ExpectStored(id, store::ScanState::kComplete, "complete");
  EXPECT_EQ(archive.header["origin"], "test");
  EXPECT_EQ(archive.header["board"], "test");
  EXPECT_EQ(archive.header["cameras"].size(), 2u);
  EXPECT_TRUE(archive.header["calibration_sha256"].is_null());
  const nlohmann::json& footer = *archive.footer;
  EXPECT_EQ(footer["dropped"], 0);

  // Every frame: its camera's next sequence number (nothing lost), lasers on, one peak per
  // column on the stripe row of the file it replays, and a position on the sweep.
  std::map<int, std::vector<const FrameRecord*>> by_camera;
  for (const FrameRecord& f : archive.frames) by_camera[f.camera].push_back(&f);
  ASSERT_EQ(by_camera.size(), 2u);
  const double sweep_s = (kSweepEnd - kSweepStart) / kSpeed;
  for (auto& [camera, frames] : by_camera) {
    std::sort(frames.begin(), frames.end(),
              [](auto* a, auto* b) { return a->sequence < b->sequence; });
    EXPECT_EQ(footer["frames"][camera], frames.size());
    EXPECT_GE(frames.size(), static_cast<size_t>(0.8 * sweep_s * 30)) << "camera " << camera;
    EXPECT_LE(frames.size(), static_cast<size_t>(1.5 * sweep_s * 30 + 10)) << "camera " << camera;
    for (size_t i = 0; i < frames.size(); ++i) {
      const FrameRecord& f = *frames[i];
      if (i > 0) {
        EXPECT_EQ(f.sequence, frames[i - 1]->sequence + 1);
        EXPECT_GE(f.slide_position_mm, frames[i - 1]->slide_position_mm - 1e-6);
        EXPECT_GT(f.timestamp_ns, frames[i - 1]->timestamp_ns);
      }
      // The first frame may have begun its exposure just before the lasers went on; it is
      // then recorded as lasers off. Every later one is lit.
      if (i > 0) {
        EXPECT_TRUE(f.lasers_on) << "sequence " << f.sequence;
      }
      EXPECT_GE(f.slide_position_mm, kSweepStart - 1.0);
      EXPECT_LE(f.slide_position_mm, kSweepEnd + 1.0);
      ASSERT_EQ(f.peaks.size(), static_cast<size_t>(kWidth)) << "sequence " << f.sequence;
      for (const Peak& p : f.peaks) EXPECT_NEAR(p.v, StripeRow(f.sequence), 0.1);
    }
    // The sweep was covered: from near its start to near its end.
    EXPECT_LT(frames.front()->slide_position_mm, kSweepStart + 20.0);
    EXPECT_GT(frames.back()->slide_position_mm, kSweepEnd - 20.0);
  }
  EXPECT_EQ(footer["peaks"], archive.frames.size() * kWidth);

  const std::vector<SequencerState> expected = {SequencerState::kHoming, SequencerState::kArming,
                                                SequencerState::kSweeping,
                                                SequencerState::kFinishing, SequencerState::kDone};
  EXPECT_EQ(States(), expected);
  std::lock_guard lock(events_mutex_);
  EXPECT_TRUE(std::any_of(events_.begin(), events_.end(), [](const ScanEvent& e) {
    return e.type == ScanEvent::Type::kProgress && e.status.progress > 0.0;
  }));
}

TEST_F(SequencerTest, ButtonStartsAScanAndAPressDuringItAborts) {
  MakeSequencer();
  PressButton();
  ASSERT_TRUE(WaitSweptPast(30.0));
  const std::string id = sequencer_->Status().scan_id;
  const int64_t press_ns = hal::SteadyNowNs();
  PressButton();
  ASSERT_TRUE(WaitState(SequencerState::kAborted));
  EXPECT_TRUE(LasersLow());
  // The press is confirmed after the 5 ms debounce; the lines go low within 50 ms of it.
  EXPECT_LE(LasersOffNs() - press_ns, 55 * kMs);
  EXPECT_NE(sequencer_->Status().reason.find("button"), std::string::npos);
  const ScanArchive archive = ExpectStored(id, store::ScanState::kAborted, "aborted");
  EXPECT_EQ(archive.header["origin"], "button");
  EXPECT_GT(archive.frames.size(), 0u);
  // The next press starts a new scan.
  PressButton();
  ASSERT_TRUE(WaitState(SequencerState::kDone));
  EXPECT_NE(sequencer_->Status().scan_id, id);
  EXPECT_TRUE(LasersLow());
}

TEST_F(SequencerTest, DriveFaultMidSweepTripsWithin50ms) {
  MakeSequencer();
  const FinishedScan earlier = ScanToTheEnd();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitSweptPast(30.0));
  const int64_t fault_ns = hal::SteadyNowNs();
  sim_->InjectFault(0x42);
  ASSERT_TRUE(WaitState(SequencerState::kFault));
  EXPECT_TRUE(LasersLow());
  const int64_t off_ms = (LasersOffNs() - fault_ns) / kMs;
  EXPECT_LE(off_ms, 50);
  std::printf("drive fault -> lasers off: %.1f ms\n", (LasersOffNs() - fault_ns) * 1e-6);
  EXPECT_EQ(sequencer_->Status().reason, "drive fault 66");
  const ScanArchive archive = ExpectStored(id, store::ScanState::kFault, "fault");
  EXPECT_EQ((*archive.footer)["reason"], "drive fault 66");
  EXPECT_GT(archive.frames.size(), 0u);
  EXPECT_FALSE(sim_->State().model.moving);
  ExpectIntact(earlier);
  // The next start clears the latched fault and scans.
  sequencer_->StartScan("test");
  EXPECT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
}

TEST_F(SequencerTest, DriveNotAnsweringTrips) {
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitSweptPast(30.0));
  const int64_t silent_ns = hal::SteadyNowNs();
  sim_->SetResponding(false);
  ASSERT_TRUE(WaitState(SequencerState::kFault));
  EXPECT_TRUE(LasersLow());
  // Silence is only known after drive_stale (150 ms); then the lines go low at once.
  const int64_t off_ns = LasersOffNs() - silent_ns;
  std::printf("drive silent -> lasers off: %.1f ms\n", off_ns * 1e-6);
  EXPECT_LE(off_ns, options_.supervisor.drive_stale.count() + 50 * kMs);
  const std::optional<Trip> trip = sequencer_->last_trip();
  ASSERT_TRUE(trip.has_value());
  EXPECT_LE(trip->safe_ns - trip->detected_ns, 50 * kMs);
  // The reason says how old the last answer was: at least drive_stale, and not the age
  // of some answer from before the silence began.
  const std::string reason = sequencer_->Status().reason;
  int age_ms = -1;
  ASSERT_EQ(std::sscanf(reason.c_str(), "drive not answering (last answer %d ms ago)", &age_ms), 1)
      << reason;
  EXPECT_GE(age_ms, 150) << reason;
  EXPECT_LE(age_ms * kMs, hal::SteadyNowNs() - silent_ns + 20 * kMs) << reason;
  const ScanArchive archive = ExpectStored(id, store::ScanState::kFault, "fault");
  // The supervisor's Stop() to the silent drive takes its retries (~0.3 s) before the
  // control loop hears of the trip; frames keep arriving meanwhile. Those exposed once the
  // lines were low are recorded dark, those before the silence lit (but a first frame
  // that began before the lasers went on).
  const int64_t lines_low_ns = LasersOffNs();
  size_t dark_after = 0, lit_before = 0;
  std::map<int, bool> first;
  for (const FrameRecord& f : archive.frames) {
    const bool is_first = first.emplace(f.camera, true).second;
    if (f.timestamp_ns >= lines_low_ns) {
      EXPECT_FALSE(f.lasers_on) << "camera " << int{f.camera} << " sequence " << f.sequence;
      ++dark_after;
    } else if (f.timestamp_ns < silent_ns && !is_first) {
      EXPECT_TRUE(f.lasers_on) << "camera " << int{f.camera} << " sequence " << f.sequence;
      ++lit_before;
    }
  }
  std::printf("frames recorded after the lines went low: %zu (dark), before the silence: %zu\n",
              dark_after, lit_before);
  EXPECT_GT(dark_after, 0u);
  EXPECT_GT(lit_before, 0u);
}

TEST_F(SequencerTest, DriveSilentWhileHomingFaultsWithoutLaserLight) {
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(Eventually([&] { return sim_->State().model.homing; }));
  sim_->SetResponding(false);
  ASSERT_TRUE(WaitState(SequencerState::kFault));
  EXPECT_NE(sequencer_->Status().reason.find("drive not answering"), std::string::npos)
      << sequencer_->Status().reason;
  EXPECT_TRUE(LasersLow());
  for (const auto* line : laser_lines_) {
    const std::vector<bool> h = line->history();
    EXPECT_EQ(std::count(h.begin(), h.end(), true), 0) << line->name();
  }
  const ScanArchive archive = ExpectStored(id, store::ScanState::kFault, "fault");
  EXPECT_TRUE(archive.frames.empty());
}

TEST_F(SequencerTest, CameraStallTrips) {
  MakeSequencer();
  const FinishedScan earlier = ScanToTheEnd();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitSweptPast(30.0));
  cameras_[1]->SetStalled(true);
  const int64_t stall_ns = hal::SteadyNowNs();
  // (A frame that passed the stall check just before is handed on within microseconds.)
  std::this_thread::sleep_for(milliseconds(5));
  const std::vector<uint64_t> before_stall = cameras_[1]->Delivered();
  ASSERT_TRUE(WaitState(SequencerState::kFault));
  EXPECT_TRUE(LasersLow());
  const int64_t off_ns = LasersOffNs() - stall_ns;
  std::printf("camera stall -> lasers off: %.1f ms\n", off_ns * 1e-6);
  EXPECT_LE(off_ns, options_.supervisor.camera_stall.count() + 50 * kMs);
  const std::optional<Trip> trip = sequencer_->last_trip();
  ASSERT_TRUE(trip.has_value());
  EXPECT_LE(trip->safe_ns - trip->detected_ns, 50 * kMs);
  EXPECT_NE(sequencer_->Status().reason.find("camera lower stalled"), std::string::npos);
  const ScanArchive archive = ExpectStored(id, store::ScanState::kFault, "fault");
  ExpectIntact(earlier);

  // Every frame the stalled camera delivered since the sweep began is stored, in order:
  // the supervisor's trip discards nothing that was already on its way to the archive.
  std::vector<uint64_t> stored[2];
  for (const FrameRecord& f : archive.frames) {
    stored[f.camera].push_back(f.sequence);
    if (f.camera == 1) {
      EXPECT_LT(f.timestamp_ns, stall_ns) << "sequence " << f.sequence;
    }
  }
  ASSERT_EQ(cameras_[1]->Delivered(), before_stall);  // nothing came after the stall
  ASSERT_GE(stored[1].size(), 5u);  // 30 mm of a 150 mm/s sweep at 30 fps: >= 6 frames
  const auto first = std::find(before_stall.begin(), before_stall.end(), stored[1].front());
  ASSERT_NE(first, before_stall.end());
  EXPECT_EQ(stored[1], std::vector<uint64_t>(first, before_stall.end()));
  EXPECT_EQ((*archive.footer)["frames"][1], stored[1].size());
  EXPECT_EQ((*archive.footer)["dropped"], 0);
  // The other camera went on until the trip, ~250 ms (7 frames) longer.
  EXPECT_GE(stored[0].size(), stored[1].size() + 3);
}

// Frames that take the host longer than the stall window to make (a renderer on a busy
// machine) are late, not a stall: the supervisor judges on the camera's own clock, which
// stands still meanwhile. (On the steady clock this faulted "camera lower stalled".)
TEST_F(SequencerTest, FramesLaterThanTheStallWindowAreNotAStall) {
  auto slow = std::make_unique<SlowRenderCamera>(milliseconds(300));
  hal::CameraConfig config = cameras_[1]->config();
  slow->Configure(config);
  cameras_[1] = std::make_unique<FaultyCamera>(std::move(slow));
  ASSERT_GT(300 * kMs, options_.supervisor.camera_stall.count());
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
  const ScanArchive archive = ExpectStored(id, store::ScanState::kComplete, "complete");
  std::vector<const FrameRecord*> lower;
  for (const FrameRecord& f : archive.frames) {
    if (f.camera == 1) lower.push_back(&f);
  }
  // A 1 s sweep at one frame made per >= 300 ms; each on its stripe row.
  ASSERT_GE(lower.size(), 2u);
  EXPECT_LE(lower.size(), 4u);
  for (size_t i = 0; i < lower.size(); ++i) {
    if (i > 0) {
      EXPECT_EQ(lower[i]->sequence, lower[i - 1]->sequence + 1);
      EXPECT_GT(lower[i]->timestamp_ns, lower[i - 1]->timestamp_ns + 33 * kMs);
    }
    ASSERT_FALSE(lower[i]->peaks.empty());
    EXPECT_NEAR(lower[i]->peaks[0].v, StripeRow(lower[i]->sequence), 0.1);
  }
  EXPECT_EQ((*archive.footer)["dropped"], 0);
}

TEST_F(SequencerTest, DroppedFramesAreCountedAndTheScanCompletes) {
  cameras_[0]->SetDropEveryNth(4);
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitState(SequencerState::kDone)) << sequencer_->Status().reason;
  EXPECT_TRUE(LasersLow());
  const ScanArchive archive = ExpectStored(id, store::ScanState::kComplete, "complete");
  std::vector<uint32_t> sequences;
  for (const FrameRecord& f : archive.frames) {
    if (f.camera == 0) sequences.push_back(f.sequence);
  }
  std::sort(sequences.begin(), sequences.end());
  ASSERT_GT(sequences.size(), 10u);
  const uint64_t gaps = sequences.back() - sequences.front() + 1 - sequences.size();
  const uint64_t counted = (*archive.footer)["camera_dropped"][0];
  // Every gap is counted; a drop just before the first or after the last stored frame
  // counts without leaving a gap.
  EXPECT_GE(counted, gaps);
  EXPECT_LE(counted, gaps + 2);
  EXPECT_GE(gaps, sequences.size() / 3 - 1);
  EXPECT_EQ((*archive.footer)["camera_dropped"][1], 0);
  EXPECT_EQ(sequencer_->Status().dropped, counted);
}

TEST_F(SequencerTest, MaxLaserOnTimeTrips) {
  options_.supervisor.max_laser_on_s = 0.3;
  MakeSequencer();
  const std::string id = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitState(SequencerState::kFault));
  EXPECT_TRUE(LasersLow());
  int64_t sweeping_ns = 0;
  {
    std::lock_guard lock(events_mutex_);
    for (const ScanEvent& e : events_) {
      if (e.type == ScanEvent::Type::kState && e.status.state == SequencerState::kSweeping) {
        sweeping_ns = e.status.updated_ns;
      }
    }
  }
  ASSERT_GT(sweeping_ns, 0);
  EXPECT_LE(LasersOffNs() - sweeping_ns, 350 * kMs);
  // (The lasers go on just before the state changes to sweeping.)
  EXPECT_GE(LasersOffNs() - sweeping_ns, 280 * kMs);
  EXPECT_NE(sequencer_->Status().reason.find("max_laser_on_s"), std::string::npos);
  ExpectStored(id, store::ScanState::kFault, "fault");
}

TEST_F(SequencerTest, ApiAbortAndBusy) {
  MakeSequencer();
  sequencer_->Abort("nothing to abort");  // a no-op while idle
  EXPECT_EQ(sequencer_->Status().state, SequencerState::kIdle);
  const std::string id = sequencer_->StartScan("api");
  try {
    sequencer_->StartScan("api");
    ADD_FAILURE() << "a second start while scanning must be refused";
  } catch (const ScanControlError& e) {
    EXPECT_EQ(e.kind(), ScanControlError::Kind::kBusy);
  }
  ASSERT_TRUE(WaitSweptPast(10.0));
  sequencer_->Abort("operator stop");
  ASSERT_TRUE(WaitState(SequencerState::kAborted));
  EXPECT_TRUE(LasersLow());
  EXPECT_EQ(sequencer_->Status().reason, "operator stop");
  const ScanArchive archive = ExpectStored(id, store::ScanState::kAborted, "aborted");
  EXPECT_EQ((*archive.footer)["reason"], "operator stop");
}

TEST_F(SequencerTest, DiskFullIsACleanFaultAndKeepsEarlierScans) {
  MakeSequencer();
  const std::string first = sequencer_->StartScan("test");
  ASSERT_TRUE(WaitState(SequencerState::kDone));
  const size_t first_frames = ReadScanFile(store_->Path(first)).frames.size();

  // A file size limit makes writes past 48 KiB fail with EFBIG, as a full disk would
  // with ENOSPC (SIGXFSZ ignored so the write returns the error).
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = 48 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  const std::string second = sequencer_->StartScan("test");
  const bool faulted = WaitState(SequencerState::kFault);
  setrlimit(RLIMIT_FSIZE, &old_limit);
  ASSERT_TRUE(faulted) << sequencer_->Status().reason;
  EXPECT_TRUE(LasersLow());
  EXPECT_NE(sequencer_->Status().reason.find("scan store"), std::string::npos);
  EXPECT_FALSE(sim_->State().model.moving);

  // The earlier scan is intact; the failed one is kept as a readable prefix.
  const ScanArchive kept = ExpectStored(first, store::ScanState::kComplete, "complete");
  EXPECT_EQ(kept.frames.size(), first_frames);
  const store::ScanInfo info = store_->Get(second);
  EXPECT_EQ(info.state, store::ScanState::kPartial) << info.reason;
  const ScanArchive prefix = ReadScanFile(store_->Path(second));
  EXPECT_GT(prefix.frames.size(), 0u);
  EXPECT_FALSE(prefix.report.complete);
}

TEST_F(SequencerTest, CaptureWhileIdle) {
  MakeSequencer();
  const CapturedFrame frame = sequencer_->Capture("lower", true);
  EXPECT_EQ(frame.camera, "lower");
  EXPECT_TRUE(frame.lasers_on);
  ASSERT_EQ(frame.width, kWidth);
  ASSERT_EQ(frame.height, kHeight);
  ASSERT_EQ(frame.pixels.size(), static_cast<size_t>(kWidth * kHeight));
  // One of the replayed files: its brightest row is a stripe row.
  int brightest = 0;
  for (int v = 0; v < kHeight; ++v) {
    if (frame.pixels[v * kWidth] > frame.pixels[brightest * kWidth]) brightest = v;
  }
  EXPECT_EQ((brightest - 30) % 5, 0);
  EXPECT_TRUE(LasersLow());
  EXPECT_TRUE(LasersWereOn());
  try {
    sequencer_->Capture("side", false);
    ADD_FAILURE() << "an unknown camera must be refused";
  } catch (const ScanControlError& e) {
    EXPECT_EQ(e.kind(), ScanControlError::Kind::kInvalidArgument);
  }
}

TEST_F(SequencerTest, TheControlLoopKeepsTheLaserInterlockRunningThroughASweep) {
  ASSERT_NE(interlock_, nullptr);
  MakeSequencer();
  sequencer_->StartScan("test");
  ASSERT_TRUE(WaitSweptPast(5.0));
  // Sampled every ~1 ms for 0.5 s: the pulse kept the lasers lit. A loaded machine (qemu
  // beside a build) once let one 45 ms pulse run out for a sample (1 of 423): allowed up
  // to 2 %, where a loop that stopped kicking would leave the rest of the window dark.
  int dark = 0, samples = 0;
  for (const auto end = std::chrono::steady_clock::now() + milliseconds(500);
       std::chrono::steady_clock::now() < end; ++samples) {
    if (!interlock_->OutputHigh(hal::SteadyNowNs())) ++dark;
    std::this_thread::sleep_for(std::chrono::microseconds(1000));
  }
  EXPECT_LE(dark, samples / 50) << "of " << samples;
  // Without kicks (the sequencer gone: a stand-in for a stuck loop) it runs out a pulse
  // after the last one.
  sequencer_.reset();
  const int64_t last = interlock_->last_trigger_ns();
  EXPECT_FALSE(interlock_->OutputHigh(last + interlock_->pulse().count()));
  std::this_thread::sleep_for(interlock_->pulse());
  EXPECT_FALSE(interlock_->OutputHigh(hal::SteadyNowNs()));
}

}  // namespace
}  // namespace mirrorscan::scan

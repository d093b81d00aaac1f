#include "firmware/board/devices.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <stdlib.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "boards/virtual/drive_sim/drive_sim.h"
#include "firmware/board/virtual/linked_simulator.h"
#include "firmware/board/virtual/simulated_drive.h"
#include "firmware/hal/hardware_error.h"
#include "firmware/hal/libcamera/libcamera_loader.h"
#include "firmware/hal/replay/replay_camera.h"
#include "tests/support/temp_dir.h"
#if MIRRORSCAN_HAS_RENDERER
#include "boards/virtual/renderer.h"
#endif

namespace mirrorscan::board {
namespace {

namespace fs = std::filesystem;
const fs::path kVirtualBoard =
    fs::path(MIRRORSCAN_SOURCE_DIR) / "boards" / "virtual" / "board.json";

nlohmann::json VirtualBoard() { return JsonReader::ParseFile(kVirtualBoard); }

// The simulator as mirrorscand links it (none in the firmware-only build).
DeviceOptions Linked() {
  DeviceOptions options;
  options.simulator = LinkedSimulator();
  return options;
}

// The drive simulator alone: it builds for the board too, the renderer does not.
DeviceOptions DriveSimulatorOnly() {
  DeviceOptions options;
  options.simulator.serve_drive = [] { return std::make_unique<SimulatedModbusDrive>(); };
  return options;
}

// The simulator's state behind a board's virtual drive.
virtual_cabinet::DriveSimState SimState(BoardDevices& devices) {
  return dynamic_cast<SimulatedModbusDrive&>(*devices.drive_sim).sim().State();
}

std::string ErrorOf(const nlohmann::json& board, const DeviceOptions& options = Linked()) {
  try {
    MakeBoardDevices(BoardConfig::Parse(board, kVirtualBoard.string()), options);
  } catch (const hal::HardwareError& e) {
    return e.what();
  }
  return "";
}

// The virtual board's hardware without the renderer: replay cameras.
class ReplayBoardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::vector<uint8_t> pixels(64 * 48, 10);
    hal::WritePgm(dir_ / "000.pgm", 64, 48, pixels.data());
    board_ = VirtualBoard();
    for (auto& camera : board_["cameras"]) {
      camera.erase("id");
      camera["backend"] = "replay";
      camera["path"] = dir_.path().string();
      camera["width"] = 64;
      camera["height"] = 48;
    }
    // No two cameras may share a source: the same folder spelled differently.
    board_["cameras"][1]["path"] = (dir_ / ".").string();
    board_["cameras"][2]["path"] = (dir_ / "." / ".").string();
  }
  const test_support::TempDir dir_{"devices_test"};
  nlohmann::json board_;
};

TEST_F(ReplayBoardTest, VirtualDriveAnswersOverModbusAndLinesStartOff) {
  BoardDevices d =
      MakeBoardDevices(BoardConfig::Parse(board_, kVirtualBoard.string()), DriveSimulatorOnly());
  ASSERT_TRUE(d.drive_sim);
  ASSERT_EQ(d.cameras.size(), 3u);
  EXPECT_EQ(d.cameras[0]->config().width, 64);
  // The Modbus path reaches the simulator: a command shows up in its state.
  const uint64_t before = SimState(d).requests;
  d.drive->Enable(true);
  EXPECT_TRUE(d.drive->Status().enabled);
  EXPECT_TRUE(SimState(d).model.enabled);
  EXPECT_GT(SimState(d).requests, before);
  EXPECT_NEAR(d.drive->Position(), SimState(d).model.position_mm, 0.01);
  ASSERT_EQ(d.virtual_lasers.size(), 3u);
  for (auto* line : d.virtual_lasers) EXPECT_FALSE(line->driven());
  d.gpio.lasers->SetAll(true);
  for (auto* line : d.virtual_lasers) EXPECT_TRUE(line->driven());
  ASSERT_NE(d.virtual_button, nullptr);
  EXPECT_TRUE(d.button_active_low);
}

// A libcamera camera goes to the dlopen'ed module and nowhere else: with the module
// missing the board fails, naming the file (no fallback to another camera).
TEST(DevicesTest, LibcameraCameraWithoutTheModuleFails) {
  const test_support::TempDir empty_dir("devices_test_no_module");
  setenv(hal::kModuleDirEnv, empty_dir.path().c_str(), 1);
  nlohmann::json board = VirtualBoard();
  for (int i = 0; i < 3; ++i) {
    board["cameras"][i]["backend"] = "libcamera";
    board["cameras"][i]["id"] = "/base/imx219@" + std::to_string(i);
  }
  const std::string error = ErrorOf(board, DriveSimulatorOnly());
  unsetenv(hal::kModuleDirEnv);
  EXPECT_NE(error.find(hal::kLibcameraModuleFile), std::string::npos) << error;
}

#if MIRRORSCAN_CAN_LOAD_LIBCAMERA
// Natively the real module loads; this machine has no camera, so the id is not found and
// the error says which ids exist. (Never under qemu: loading libcamera hangs there.)
TEST(DevicesTest, LibcameraCameraThatIsNotThereFails) {
  nlohmann::json board = VirtualBoard();
  board["cameras"][0]["backend"] = "libcamera";
  board["cameras"][0]["id"] = "/base/imx219";
  const std::string error = ErrorOf(board);
  EXPECT_NE(error.find("/base/imx219"), std::string::npos) << error;
}
#endif

TEST(DevicesTest, VirtualCameraNeedsTheVirtualDrive) {
  // A real Modbus drive (the simulator, reached as an external one) with virtual cameras:
  // the renderer could not know where the slide is.
  auto sim = virtual_cabinet::DriveSim::ServeTcp({});
  nlohmann::json board = VirtualBoard();
  board["drive"] = JsonReader::ParseFile(kVirtualBoard.parent_path().parent_path() / "rpi5" /
                                         "board.json")["drive"];
  board["drive"]["link"] = {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", sim->port()}};
  // A renderer is there (a stand-in: the firmware-only build has none), so what is
  // refused is the drive.
  DeviceOptions options;
  options.simulator.open_cabinet = [](const fs::path&, double) {
    ADD_FAILURE() << "the cabinet was opened";
    return std::unique_ptr<VirtualCabinet>();
  };
  const std::string error = ErrorOf(board, options);
  EXPECT_NE(error.find("needs drive.backend and gpio.backend \"virtual\""), std::string::npos)
      << error;
}

#if MIRRORSCAN_HAS_RENDERER
// The frame shows the lasers where the drive put the slide: moved to 450 mm (the sweep
// starts at 0, so the scene's lasers are 450 mm past their start: t = 3 s), the stripes
// the extractor finds in a live frame are where the renderer's truth puts them for the
// drive's own position.
TEST(DevicesTest, VirtualCamerasRenderTheSlideWhereTheDriveIs) {
  const BoardConfig config = BoardConfig::Load(kVirtualBoard);
  BoardDevices d = MakeBoardDevices(config, Linked());
  ASSERT_EQ(d.cameras.size(), 3u);
  EXPECT_EQ(d.cameras[0]->config().width, 1024);
  d.drive->Enable(true);
  d.drive->Home(std::chrono::seconds(10));
  d.drive->SetSpeed(500.0);
  d.drive->Start(450.0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (d.drive->Status().moving || std::abs(d.drive->Position() - 450.0) > 0.01) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "the drive did not reach 450 mm";
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const double slide_mm = SimState(d).model.position_mm;
  d.gpio.lasers->SetAll(true);
  // The lasers emit only while the interlock is kicked (the sequencer's tick does it).
  ASSERT_NE(d.gpio.interlock, nullptr);
  std::atomic<bool> kicking{true};
  std::thread kicker([&] {
    while (kicking) {
      d.gpio.interlock->Kick();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });

  std::mutex mutex;
  std::condition_variable got;
  std::vector<std::vector<Peak>> frames;
  d.cameras[0]->Start([&](hal::Frame frame) {
    std::vector<Peak> peaks = ExtractPeaks(frame.view(), config.peaks);
    std::lock_guard lock(mutex);
    // A frame exposed before the first kick, or while a starved kicker let the interlock's
    // pulse lapse (a loaded machine), is dark: it says nothing about where the slide is.
    if (frame.view().width == 1024 && !peaks.empty() && frames.size() < 2)
      frames.push_back(std::move(peaks));
    got.notify_all();
  });
  std::unique_lock lock(mutex);
  EXPECT_TRUE(got.wait_for(lock, std::chrono::seconds(20), [&] { return frames.size() >= 2; }));
  lock.unlock();
  d.cameras[0]->Stop();
  kicking = false;
  kicker.join();
  d.gpio.lasers->SetAll(false);
  ASSERT_EQ(frames.size(), 2u);

  const virtual_cabinet::Renderer renderer(virtual_cabinet::Scene::Load(config.virtual_scene));
  const double t = (slide_mm - config.scan.sweep_start_mm) / renderer.scene().lasers.speed_mm_s;
  const auto truth = renderer.Truth(0, t);
  ASSERT_GT(truth.size(), 300u);
  for (const std::vector<Peak>& peaks : frames) {
    // Each truth point found by a peak in its column within 1 px, and how far.
    size_t found = 0, false_peaks = 0;
    double sum2 = 0;
    for (const auto& p : truth) {
      double best = 1e9;
      for (const Peak& q : peaks)
        if (q.u == p.u) best = std::min(best, std::abs(q.v - p.v));
      if (best > 1.0) continue;
      ++found;
      sum2 += best * best;
    }
    for (const Peak& q : peaks) {
      bool near = false;
      for (const auto& p : truth) near = near || (q.u == p.u && std::abs(q.v - p.v) <= 1.0);
      false_peaks += near ? 0 : 1;
    }
    const double rms = std::sqrt(sum2 / std::max<size_t>(found, 1));
    std::printf(
        "slide %.2f mm: %zu of %zu truth points found, RMS %.4f px; %zu of %zu peaks false\n",
        slide_mm, found, truth.size(), rms, false_peaks, peaks.size());
    EXPECT_GT(found, 0.97 * truth.size());
    EXPECT_LT(rms, 0.15);
    EXPECT_LT(false_peaks, 0.02 * peaks.size());
  }
}
#else
// The board's mirrorscand links no simulator: the virtual board is one error naming what
// it would need.
TEST(DevicesTest, FirmwareOnlyBuildRefusesTheVirtualBoard) {
  const std::string error = ErrorOf(VirtualBoard());
  EXPECT_NE(error.find("drive.backend \"virtual\", cameras upper, lower, up \"virtual\" need the "
                       "virtual cabinet's simulator"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("firmware-only build"), std::string::npos) << error;
}
#endif

// Without the renderer a board with virtual cameras is refused before any device starts,
// never run with something else in their place.
TEST(DevicesTest, VirtualCamerasWithoutTheRendererAreRefused) {
  const std::string error = ErrorOf(VirtualBoard(), DriveSimulatorOnly());
  EXPECT_NE(error.find("cameras upper, lower, up \"virtual\" need the virtual cabinet's simulator"),
            std::string::npos)
      << error;
  EXPECT_EQ(error.find("drive.backend"), std::string::npos) << error;
}

}  // namespace
}  // namespace mirrorscan::board

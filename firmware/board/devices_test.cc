#include "firmware/board/devices.h"

#include <filesystem>
#include <string>

#include <stdlib.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "firmware/hal/hardware_error.h"
#include "firmware/hal/libcamera/libcamera_loader.h"
#include "firmware/hal/replay/replay_camera.h"

namespace mirrorscan::board {
namespace {

namespace fs = std::filesystem;
const fs::path kVirtualBoard =
    fs::path(MIRRORSCAN_SOURCE_DIR) / "boards" / "virtual" / "board.json";

nlohmann::json VirtualBoard() { return JsonReader::ParseFile(kVirtualBoard); }

std::string ErrorOf(const nlohmann::json& board) {
  try {
    MakeBoardDevices(BoardConfig::Parse(board, kVirtualBoard.string()));
  } catch (const hal::HardwareError& e) {
    return e.what();
  }
  return "";
}

// The virtual board's hardware without the renderer: replay cameras.
class ReplayBoardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/devices_test.XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
    std::vector<uint8_t> pixels(64 * 48, 10);
    hal::WritePgm(dir_ / "000.pgm", 64, 48, pixels.data());
    board_ = VirtualBoard();
    for (auto& camera : board_["cameras"]) {
      camera.erase("id");
      camera["backend"] = "replay";
      camera["path"] = dir_.string();
      camera["width"] = 64;
      camera["height"] = 48;
    }
    board_["cameras"][1]["path"] = (dir_ / ".").string();
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  nlohmann::json board_;
};

TEST_F(ReplayBoardTest, VirtualDriveAnswersOverModbusAndLinesStartOff) {
  BoardDevices d = MakeBoardDevices(BoardConfig::Parse(board_, kVirtualBoard.string()));
  ASSERT_TRUE(d.drive_sim);
  ASSERT_EQ(d.cameras.size(), 2u);
  EXPECT_EQ(d.cameras[0]->config().width, 64);
  // The Modbus path reaches the simulator: a command shows up in its state.
  const uint64_t before = d.drive_sim->State().requests;
  d.drive->Enable(true);
  EXPECT_TRUE(d.drive->Status().enabled);
  EXPECT_TRUE(d.drive_sim->State().model.enabled);
  EXPECT_GT(d.drive_sim->State().requests, before);
  EXPECT_NEAR(d.drive->Position(), d.drive_sim->State().model.position_mm, 0.01);
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
  const std::filesystem::path empty_dir = std::filesystem::temp_directory_path() /
                                          ("devices_test_no_module_" + std::to_string(getpid()));
  std::filesystem::create_directories(empty_dir);
  setenv(hal::kModuleDirEnv, empty_dir.c_str(), 1);
  nlohmann::json board = VirtualBoard();
  board["cameras"][0]["backend"] = "libcamera";
  board["cameras"][0]["id"] = "/base/imx219";
  const std::string error = ErrorOf(board);
  unsetenv(hal::kModuleDirEnv);
  std::filesystem::remove_all(empty_dir);
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
  const std::string error = ErrorOf(board);
  EXPECT_NE(error.find("needs drive.backend and gpio.backend \"virtual\""), std::string::npos)
      << error;
}

#if MIRRORSCAN_HAS_RENDERER
TEST(DevicesTest, VirtualCamerasRenderTheSimulatedSlide) {
  BoardDevices d = MakeBoardDevices(BoardConfig::Load(kVirtualBoard));
  ASSERT_EQ(d.cameras.size(), 2u);
  EXPECT_EQ(d.cameras[0]->config().width, 1024);
  std::mutex mutex;
  std::condition_variable got;
  int frames = 0;
  d.cameras[0]->Start([&](hal::Frame frame) {
    std::lock_guard lock(mutex);
    if (frame.view().width == 1024) ++frames;
    got.notify_all();
  });
  std::unique_lock lock(mutex);
  EXPECT_TRUE(got.wait_for(lock, std::chrono::seconds(10), [&] { return frames >= 2; }));
  lock.unlock();
  d.cameras[0]->Stop();
}
#else
TEST(DevicesTest, FirmwareOnlyBuildRefusesVirtualCameras) {
  const std::string error = ErrorOf(VirtualBoard());
  EXPECT_NE(error.find("firmware-only build"), std::string::npos) << error;
}
#endif

}  // namespace
}  // namespace mirrorscan::board

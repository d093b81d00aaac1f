#include "firmware/board/board_config.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace mirrorscan::board {
namespace {

namespace fs = std::filesystem;

const fs::path kBoards = fs::path(MIRRORSCAN_SOURCE_DIR) / "boards";

std::vector<fs::path> ShippedBoards() {
  std::vector<fs::path> files;
  for (const fs::directory_entry& dir : fs::directory_iterator(kBoards)) {
    if (fs::exists(dir.path() / "board.json")) files.push_back(dir.path() / "board.json");
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(BoardConfigTest, EveryShippedBoardLoads) {
  const std::vector<fs::path> files = ShippedBoards();
  ASSERT_GE(files.size(), 3u);  // virtual, rpi4, rpi5
  for (const fs::path& file : files) {
    SCOPED_TRACE(file.string());
    BoardConfig c;
    ASSERT_NO_THROW(c = BoardConfig::Load(file));
    EXPECT_EQ(c.board, file.parent_path().filename().string());
    EXPECT_FALSE(c.description.empty());
    EXPECT_GE(c.cameras.size(), 1u);
    EXPECT_FALSE(c.gpio.lasers.empty());
    EXPECT_FALSE(c.service.listen.empty());
    // Every hardware board ships its systemd unit (the virtual one runs without systemd).
    if (c.board != "virtual") {
      EXPECT_TRUE(fs::exists(file.parent_path() / "mirrorscand.service"));
    }
  }
}

TEST(BoardConfigTest, VirtualBoardUsesVirtualBackends) {
  const BoardConfig c = BoardConfig::Load(kBoards / "virtual" / "board.json");
  ASSERT_EQ(c.cameras.size(), 3u);
  EXPECT_EQ(c.cameras[0].name, "upper");
  EXPECT_EQ(c.cameras[0].backend, CameraBackend::kVirtual);
  EXPECT_EQ(c.cameras[1].scene_camera, 1);
  EXPECT_EQ(c.cameras[2].name, "up");
  EXPECT_EQ(c.cameras[2].scene_camera, 2);
  EXPECT_EQ(c.gpio.backend, hal::GpioBackend::kVirtual);
  EXPECT_EQ(c.drive.backend, BoardDrive::Backend::kVirtual);
  EXPECT_EQ(c.gpio.lasers.size(), 3u);
  // The scene is found beside board.json, whatever the working directory.
  EXPECT_EQ(c.virtual_scene, kBoards / "virtual" / "scenes" / "mannequin.json");
  EXPECT_TRUE(std::filesystem::exists(c.virtual_scene));
  EXPECT_EQ(c.scan.camera_stall_ms, 250.0);
  // The development token stands in board.json; real boards generate theirs.
  EXPECT_EQ(c.service.token, "virtual-dev-token-not-a-secret");
  EXPECT_TRUE(c.service.token_file.empty());
}

TEST(BoardConfigTest, PiBoardsUseHardwareBackends) {
  for (const char* name : {"rpi4", "rpi5"}) {
    SCOPED_TRACE(name);
    const BoardConfig c = BoardConfig::Load(kBoards / name / "board.json");
    ASSERT_EQ(c.cameras.size(), 2u);
    for (const BoardCamera& cam : c.cameras) {
      EXPECT_EQ(cam.backend, CameraBackend::kLibcamera);
      EXPECT_FALSE(cam.id.empty());
    }
    EXPECT_EQ(c.gpio.backend, hal::GpioBackend::kGpiod);
    EXPECT_EQ(c.gpio.chip, "gpiochip0");
    ASSERT_EQ(c.drive.backend, BoardDrive::Backend::kModbus);
    EXPECT_EQ(c.drive.modbus.transport, hal::ModbusDriveConfig::Transport::kRtu);
    EXPECT_EQ(c.drive.modbus.device, "/dev/ttyAMA0");
    EXPECT_TRUE(c.service.token.empty());
    EXPECT_EQ(c.service.token_file, "/var/lib/mirrorscan/token");
  }
}

// The virtual board with one edit applied; parse errors must name "board.json" and `key`.
class BadBoardTest : public ::testing::Test {
 protected:
  void SetUp() override { json_ = JsonReader::ParseFile(kBoards / "virtual" / "board.json"); }
  // Expects exactly one ConfigError whose message starts with "board.json: <key>: ".
  void ExpectError(const std::string& key, const std::string& problem = "") {
    try {
      BoardConfig::Parse(json_, "board.json");
      FAIL() << "no error; expected one naming " << key;
    } catch (const ConfigError& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind("board.json: " + key + ": ", 0), 0u) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
    }
  }
  nlohmann::json json_;
};

TEST_F(BadBoardTest, VirtualBoardParses) { EXPECT_NO_THROW(BoardConfig::Parse(json_, "b")); }

TEST_F(BadBoardTest, VirtualCamerasNeedAScene) {
  json_.erase("virtual");
  ExpectError("virtual", "required");
}

TEST_F(BadBoardTest, UnknownKeyInVirtual) {
  json_["virtual"]["seen"] = "x.json";
  ExpectError("virtual.seen", "unknown");
}

TEST_F(BadBoardTest, CameraStallOutOfRange) {
  json_["scan"]["camera_stall_ms"] = 10;
  ExpectError("scan.camera_stall_ms");
}

TEST_F(BadBoardTest, UnknownTopLevelKey) {
  json_["lazers"] = nlohmann::json::object();
  ExpectError("lazers", "unknown");
}

// The host's sections ride along in the same file; the device ignores what is in them.
TEST_F(BadBoardTest, HostSectionsAreAllowed) {
  json_["calibration"] = {{"mirror_width_mm", 620}};
  json_["reconstruction"] = {{"bounding_cylinder", {{"radius_mm", 500}}}};
  EXPECT_NO_THROW(BoardConfig::Parse(json_, "b"));
}

TEST_F(BadBoardTest, UnknownKeyInSection) {
  json_["scan"]["speed"] = 10;
  ExpectError("scan.speed", "unknown");
}

TEST_F(BadBoardTest, BadCameraBackend) {
  json_["cameras"][1]["backend"] = "v4l2";
  ExpectError("cameras[1].backend", "libcamera");
}

TEST_F(BadBoardTest, CameraValidationNamesTheKey) {
  json_["cameras"][0]["exposure_us"] = 50000;  // longer than a 30 fps frame
  ExpectError("cameras[0].exposure_us", "frame period");
}

TEST_F(BadBoardTest, ReplayCameraNeedsPathNotId) {
  json_["cameras"][0]["backend"] = "replay";
  ExpectError("cameras[0].id", "unknown");
}

TEST_F(BadBoardTest, DuplicateCameraName) {
  json_["cameras"][1]["name"] = "upper";
  ExpectError("cameras[1].name", "twice");
}

TEST_F(BadBoardTest, NoCameras) {
  json_["cameras"] = nlohmann::json::array();
  ExpectError("cameras", "at least one");
}

TEST_F(BadBoardTest, DuplicateGpioLine) {
  json_["gpio"]["lasers"][1]["line"] = 17;
  ExpectError("gpio.lasers[1].line", "gpio.lasers[0].line");
}

TEST_F(BadBoardTest, MissingDriveLink) {
  const nlohmann::json pi = JsonReader::ParseFile(kBoards / "rpi5" / "board.json");
  json_["drive"] = pi["drive"];
  json_["drive"].erase("link");
  ExpectError("drive.link", "missing");
}

TEST_F(BadBoardTest, VirtualDriveTakesNoOtherKeys) {
  json_["drive"]["link"] = {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 1502}};
  ExpectError("drive.link", "unknown");
}

TEST_F(BadBoardTest, MissingSection) {
  json_.erase("store");
  ExpectError("store", "missing");
}

TEST_F(BadBoardTest, BadPeaks) {
  json_["peaks"]["estimator"] = "magic";
  ExpectError("peaks.estimator");
}

TEST_F(BadBoardTest, SweepLongerThanLaserLimit) {
  json_["scan"]["max_laser_on_s"] = 1;
  ExpectError("scan.max_laser_on_s", "shorter than the sweep");
}

TEST_F(BadBoardTest, SweepOutsideDriveTravel) {
  const nlohmann::json pi = JsonReader::ParseFile(kBoards / "rpi5" / "board.json");
  json_["drive"] = pi["drive"];
  json_["scan"]["sweep_end_mm"] = 2500;
  json_["scan"]["max_laser_on_s"] = 600;
  ExpectError("scan.sweep_end_mm", "travel_mm");
}

TEST_F(BadBoardTest, SpeedAboveDriveMaximum) {
  const nlohmann::json pi = JsonReader::ParseFile(kBoards / "rpi5" / "board.json");
  json_["drive"] = pi["drive"];
  json_["scan"]["speed_mm_s"] = 600;
  ExpectError("scan.speed_mm_s", "max_speed_mm_s");
}

TEST_F(BadBoardTest, RetentionMustBePositive) {
  json_["store"]["retention_scans"] = 0;
  ExpectError("store.retention_scans");
}

TEST_F(BadBoardTest, ListenNeedsAPort) {
  json_["service"]["listen"] = "127.0.0.1";
  ExpectError("service.listen", "host:port");
}

TEST_F(BadBoardTest, ServiceNeedsExactlyOneTokenSource) {
  json_["service"]["token_file"] = "/var/lib/mirrorscan/token";
  ExpectError("service.token", "exactly one");
  json_["service"].erase("token");
  json_["service"].erase("token_file");
  ExpectError("service.token", "exactly one");
}

TEST_F(BadBoardTest, ServiceTokenMustBeLongAndPlain) {
  json_["service"]["token"] = "short";
  ExpectError("service.token", "16 to 256");
  json_["service"]["token"] = "a token with spaces in it";
  ExpectError("service.token", "16 to 256");
}

TEST_F(BadBoardTest, ServiceTokenFileMustBeAbsolute) {
  json_["service"].erase("token");
  json_["service"]["token_file"] = "token";
  ExpectError("service.token_file", "absolute");
}

TEST_F(BadBoardTest, ServiceAuthReadsIsABool) {
  json_["service"]["auth_reads"] = "yes";
  ExpectError("service.auth_reads");
}

TEST(BoardConfigLoadTest, MissingFileNamesTheFile) {
  try {
    BoardConfig::Load("/nonexistent/board.json");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/board.json"), std::string::npos);
  }
}

}  // namespace
}  // namespace mirrorscan::board

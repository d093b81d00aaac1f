// scripts/factory-calibrate against the real mirrorscand on the virtual board, its cameras
// rendering the three-panel target: a good target passes and the device ends up holding
// exactly the calibration computed on the host; a target out of place fails with a reason
// and leaves the device's calibration untouched.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

extern char** environ;

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;
const fs::path kBinDir = MIRRORSCAN_BIN_DIR;

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  socklen_t length = sizeof(addr);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &length);
  ::close(fd);
  return ntohs(addr.sin_port);
}

struct Result {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

class FactoryCalibrateTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/factory_calibrate_test.XXXXXX";
    ASSERT_NE(::mkdtemp(pattern), nullptr);
    dir_ = pattern;
    token_ = json::parse(ReadFile(kSource / "boards/virtual/board.json"))["service"]["token"];
    host_ = "127.0.0.1:" + std::to_string(FreePort());
  }

  void TearDown() override {
    StopDaemon();
    fs::remove_all(dir_);
  }

  void StartDaemon(const fs::path& scene) {
    std::vector<std::string> args = {(kBinDir / "mirrorscand").string(),
                                     "--board",
                                     (kSource / "boards/virtual/board.json").string(),
                                     "--data-dir",
                                     (dir_ / "data").string(),
                                     "--listen",
                                     host_,
                                     "--scene",
                                     scene.string()};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, (dir_ / "daemon.log").c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    ASSERT_EQ(posix_spawn(&daemon_, argv[0], &actions, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (Shell(Mirrorscan() + " device status --host " + host_).exit_code != 0) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << ReadFile(dir_ / "daemon.log");
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }

  void StopDaemon() {
    if (daemon_ <= 0) return;
    ::kill(daemon_, SIGTERM);
    int status = 0;
    ::waitpid(daemon_, &status, 0);
    daemon_ = -1;
  }

  static std::string Mirrorscan() { return (kBinDir / "mirrorscan").string(); }

  Result Shell(const std::string& command) {
    const fs::path log = dir_ / "command.log";
    const std::string line = "MIRRORSCAN_BIN=" + Mirrorscan() + " MIRRORSCAN_TOKEN=" + token_ +
                             " " + command + " >" + log.string() + " 2>&1";
    const int status = std::system(line.c_str());
    Result result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.output = ReadFile(log);
    return result;
  }

  Result FactoryCalibrate(const fs::path& out) {
    return Shell((kSource / "scripts/factory-calibrate").string() + " --host " + host_ + " --out " +
                 out.string());
  }

  fs::path dir_;
  std::string token_;
  std::string host_;
  pid_t daemon_ = -1;
};

TEST_F(FactoryCalibrateTest, GoodTargetPassesAndTheDeviceHoldsTheCalibration) {
  StartDaemon(kSource / "boards/virtual/scenes/calibration.json");
  const Result run = FactoryCalibrate(dir_ / "out");
  ASSERT_EQ(run.exit_code, 0) << run.output << ReadFile(dir_ / "daemon.log");
  EXPECT_NE(run.output.find("PASS"), std::string::npos) << run.output;

  // What the device stores and serves is what the host computed, and it is a real
  // calibration of this cabinet: both cameras, both mirrors, small residuals.
  const json computed = json::parse(ReadFile(dir_ / "out/calibration.json"));
  const Result get = Shell(Mirrorscan() + " device calibration get --host " + host_ + " --out " +
                           (dir_ / "served.json").string());
  ASSERT_EQ(get.exit_code, 0) << get.output;
  EXPECT_EQ(json::parse(ReadFile(dir_ / "served.json")), computed);
  EXPECT_EQ(json::parse(ReadFile(dir_ / "data/calibration.json")), computed);
  ASSERT_EQ(computed["cameras"].size(), 2u);
  ASSERT_EQ(computed["mirrors"].size(), 2u);
  const json report = json::parse(ReadFile(dir_ / "out/report.json"));
  EXPECT_TRUE(report["ok"].get<bool>());
  for (const json& camera : report["cameras"]) {
    for (const json& view : camera["views"]) {
      EXPECT_LT(view["rms_after_px"].get<double>(), 0.15) << camera["name"] << view["view"];
    }
  }
}

TEST_F(FactoryCalibrateTest, TargetOutOfPlaceFailsAndUploadsNothing) {
  // The target turned by 3°: the calibration must refuse, not store a wrong result.
  json scene = json::parse(ReadFile(kSource / "boards/virtual/scenes/calibration.json"));
  scene["target"]["yaw_deg"] = 3.0;
  const fs::path scene_file = dir_ / "turned-target.json";
  std::ofstream(scene_file) << scene.dump(2);
  StartDaemon(scene_file);

  const Result run = FactoryCalibrate(dir_ / "out");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("FAIL"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("out of place"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "data/calibration.json"));
  EXPECT_FALSE(fs::exists(dir_ / "out/calibration.json"));
}

TEST_F(FactoryCalibrateTest, WrongTokenIsRefusedBeforeAnythingIsStored) {
  StartDaemon(kSource / "boards/virtual/scenes/calibration.json");
  token_ = "not-the-token";
  const Result run = FactoryCalibrate(dir_ / "out");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("FAIL"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "data/calibration.json"));
}

}  // namespace
}  // namespace mirrorscan

// Results back at the cabinet, end to end on loopback: mirrorscand on the virtual board,
// a pushbutton scan (SIGUSR1), `mirrorscan device watch --process` fetching, processing
// and uploading it, and the results read back from the device byte for byte; then
// `process --upload` refusing a wrong token before any work; a failing job reported and the
// watch going on (docs/cli-device.md).
#include <signal.h>

#include <fstream>
#include <memory>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/protocol/protocol.h"
#include "tests/support/daemon.h"
#include "tests/support/loopback.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test_support::ChildProcess;
using test_support::CommandResult;
using test_support::ReadFile;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;
const std::string kBin = MIRRORSCAN_BIN_DIR;

class DeviceWatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    token_ = json::parse(ReadFile(kSource / "boards/virtual/board.json"))["service"]["token"];
    json board = json::parse(ReadFile(kSource / "boards/virtual/board.json"));
    board["virtual"]["scene"] = (kSource / "boards/virtual/scenes/mannequin.json").string();
    std::ofstream(dir_ / "board.json") << board.dump(2);
    daemon_ =
        test_support::StartMirrorscand({"--board", (dir_ / "board.json").string(), "--data-dir",
                                        (dir_ / "data").string(), "--listen", host_},
                                       dir_ / "daemon.log");
    ASSERT_TRUE(test_support::WaitUntilServing(*daemon_, port_, std::chrono::seconds(30)))
        << daemon_->Log();
    // The scene's true calibration on the device, so its archives name it.
    const CommandResult truth =
        Run("sim render --scene " + (kSource / "boards/virtual/scenes/mannequin.json").string() +
                " --out " + (dir_ / "truth").string(),
            /*device=*/false);
    ASSERT_EQ(truth.exit_code, 0) << truth.err;
    const CommandResult put =
        Run("device calibration put " + (dir_ / "truth/calibration.json").string());
    ASSERT_EQ(put.exit_code, 0) << put.err;
  }

  void TearDown() override {
    if (daemon_) {
      daemon_->Signal(SIGTERM);
      EXPECT_EQ(daemon_->Wait(), 0) << daemon_->Log();
    }
  }

  CommandResult Run(const std::string& arguments, bool device = true,
                    const std::string& token = "") const {
    return test_support::RunCommand(
        "cd " + dir_.path().string() + " && MIRRORSCAN_TOKEN=" + (token.empty() ? token_ : token) +
            " " + kBin + "/mirrorscan " + arguments + (device ? " --host " + host_ : ""),
        dir_ / "stderr.txt");
  }

  const test_support::TempDir dir_{"device_watch_test"};
  const int port_ = test_support::FreeLoopbackPort();
  const std::string host_ = "127.0.0.1:" + std::to_string(port_);
  std::string token_;
  std::unique_ptr<ChildProcess> daemon_;
};

TEST_F(DeviceWatchTest, APushbuttonScanComesBackProcessedAndTheUploadNeedsTheToken) {
  test_support::ChildOptions options;
  options.env = {{"MIRRORSCAN_TOKEN", token_}};
  ChildProcess watch(
      kBin + "/mirrorscan",
      {"device", "watch", "--host", host_, "--out", (dir_ / "watch").string(), "--process",
       "--calibration", (dir_ / "truth/calibration.json").string(), "--count", "1", "--json"},
      dir_ / "watch.log", options);
  ASSERT_TRUE(watch.WaitLog("watch: following", std::chrono::seconds(30))) << watch.Log();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the event stream is open
  daemon_->Signal(SIGUSR1);                                     // the pushbutton
  ASSERT_EQ(watch.Wait(std::chrono::minutes(8)), 0) << watch.Log() << daemon_->Log();

  // The report line: fetched, processed (exit 0).
  json report;
  std::istringstream lines(watch.Log());
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("{\"", 0) == 0) report = json::parse(line);
  }
  ASSERT_TRUE(report.is_object()) << watch.Log();
  const std::string id = report.at("id");
  EXPECT_EQ(report.at("state"), "done");
  EXPECT_EQ(report.at("process_exit"), 0) << watch.Log();
  EXPECT_EQ(ReadFile(dir_ / "watch" / (id + ".mscan")), ReadFile(dir_ / "data" / (id + ".mscan")));
  const fs::path results = dir_ / "watch" / id;
  const json summary = json::parse(ReadFile(results / "summary.json"));
  EXPECT_TRUE(summary.at("ok").get<bool>()) << summary.dump();
  EXPECT_EQ(summary.at("scan_id"), id);
  // The pose check's verdict is in the report and its advice printed as soon as processed.
  ASSERT_TRUE(summary.contains("pose")) << summary.dump();
  EXPECT_EQ(report.at("pose"), summary.at("pose"));
  const std::string said = "watch: scan " + id + " pose: ";
  EXPECT_NE(watch.Log().find(said), std::string::npos) << watch.Log();
  for (const auto& advice : summary.at("pose").at("advice")) {
    EXPECT_NE(watch.Log().find(said + "say: " + advice.get<std::string>()), std::string::npos)
        << watch.Log();
  }

  // On the device: every result the folder has, byte for byte, and the scan names them.
  const json scan = json::parse(Run("device list --json").out)[0];
  EXPECT_EQ(scan.at("id"), id);
  std::vector<std::string> expected;
  for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
    if (fs::exists(results / std::string(kind.name))) expected.emplace_back(kind.name);
  }
  EXPECT_GE(expected.size(), 10u);  // mesh, seven previews, measurements, summary
  EXPECT_EQ(scan.at("results").get<std::vector<std::string>>(), expected);
  for (const std::string& name : expected) {
    EXPECT_EQ(ReadFile(dir_ / "data" / (id + ".results") / name), ReadFile(results / name)) << name;
  }

  // A wrong token: refused before any processing, exit 3, nothing new on the device.
  const auto mesh_time = fs::last_write_time(dir_ / "data" / (id + ".results") / "mesh.ply");
  const auto start = std::chrono::steady_clock::now();
  const CommandResult wrong =
      Run("process " + (dir_ / "watch" / (id + ".mscan")).string() + " --calibration " +
              (dir_ / "truth/calibration.json").string() + " --out " + (dir_ / "again").string() +
              " --upload " + host_,
          /*device=*/false, "wrong-token-wrong-token-wrong-token");
  EXPECT_EQ(wrong.exit_code, 3) << wrong.err;
  EXPECT_NE(wrong.err.find("wrong bearer token"), std::string::npos) << wrong.err;
  EXPECT_NE(wrong.err.find("nothing processed"), std::string::npos) << wrong.err;
  EXPECT_FALSE(fs::exists(dir_ / "again" / "mesh.ply"));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(60));
  EXPECT_EQ(fs::last_write_time(dir_ / "data" / (id + ".results") / "mesh.ply"), mesh_time);
}

// A job that fails (here: a calibration that is no calibration) is reported in its scan's
// line with its exit status and reason; the watch itself goes on and ends well.
TEST_F(DeviceWatchTest, AFailingJobIsReportedAndTheWatchGoesOn) {
  std::ofstream(dir_ / "broken.json") << "{\"not\": \"a calibration\"}";
  test_support::ChildOptions options;
  options.env = {{"MIRRORSCAN_TOKEN", token_}};
  ChildProcess watch(
      kBin + "/mirrorscan",
      {"device", "watch", "--host", host_, "--out", (dir_ / "watch").string(), "--process",
       "--calibration", (dir_ / "broken.json").string(), "--count", "1", "--json"},
      dir_ / "watch.log", options);
  ASSERT_TRUE(watch.WaitLog("watch: following", std::chrono::seconds(30))) << watch.Log();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the event stream is open
  daemon_->Signal(SIGUSR1);                                     // the pushbutton
  ASSERT_EQ(watch.Wait(std::chrono::minutes(8)), 0) << watch.Log() << daemon_->Log();
  json report;
  std::istringstream lines(watch.Log());
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("{\"", 0) == 0) report = json::parse(line);
  }
  ASSERT_TRUE(report.is_object()) << watch.Log();
  EXPECT_EQ(report.at("process_exit"), 2) << watch.Log();
  EXPECT_NE(report.at("process_error").get<std::string>().find("broken.json"), std::string::npos)
      << report.dump();
  EXPECT_NE(watch.Log().find(", process exit 2: "), std::string::npos) << watch.Log();
  EXPECT_TRUE(fs::exists(dir_ / "watch" / (report.at("id").get<std::string>() + ".mscan")));
}

}  // namespace
}  // namespace mirrorscan

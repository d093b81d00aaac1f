// The whole appliance on loopback: mirrorscand on the virtual board (rendered cameras,
// simulated drive over Modbus, virtual GPIO, the real sequencer, store and API), driven by the
// `mirrorscan device` CLI: a scan started and followed to its end, the archive fetched and
// compared byte for byte with the store's file, and a live --follow of a second scan.
#include <signal.h>

#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "tests/support/daemon.h"
#include "tests/support/loopback.h"
#include "tests/support/process.h"
#include "tests/support/scene_truth.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

using test_support::ChildProcess;
using test_support::CommandResult;
using test_support::ReadFile;

class DeviceEndToEndTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dir_ / "host");
    token_ = json::parse(ReadFile(kSource / "boards/virtual/board.json"))["service"]["token"];
    daemon_ = test_support::StartMirrorscand({"--board", WriteBoard().string(), "--data-dir",
                                              (dir_ / "data").string(), "--listen", host_},
                                             dir_ / "daemon.log");
    ASSERT_TRUE(test_support::WaitUntilServing(*daemon_, port_, std::chrono::seconds(30)))
        << daemon_->Log();
  }

  void TearDown() override {
    if (daemon_) {
      daemon_->Signal(SIGTERM);
      EXPECT_EQ(daemon_->Wait(), 0) << daemon_->Log();
    }
  }

  // The virtual board as shipped (both cameras rendering the mannequin), with the sweep
  // shortened to 300 mm (2 s) to keep the test short.
  fs::path WriteBoard() {
    json board = json::parse(ReadFile(kSource / "boards/virtual/board.json"));
    board["scan"]["sweep_start_mm"] = 700;
    board["scan"]["sweep_end_mm"] = 1000;
    board["virtual"]["scene"] = (kSource / "boards/virtual/scenes/mannequin.json").string();
    const fs::path file = dir_ / "board.json";
    std::ofstream(file) << board.dump(2);
    return file;
  }

  CommandResult Run(const std::string& arguments) const {
    return test_support::RunCommand(
        "cd " + (dir_ / "host").string() + " && MIRRORSCAN_TOKEN=" + token_ + " " +
            MIRRORSCAN_BIN_DIR + "/mirrorscan " + arguments + " --host " + host_,
        dir_ / "stderr.txt");
  }

  const test_support::TempDir dir_{"device_e2e_test"};
  const int port_ = test_support::FreeLoopbackPort();
  const std::string host_ = "127.0.0.1:" + std::to_string(port_);
  std::string token_;
  std::unique_ptr<ChildProcess> daemon_;
};

TEST_F(DeviceEndToEndTest, ScanWaitFetchAndFollowMatchTheStoredArchive) {
  const CommandResult scan = Run("device scan --wait --json");
  ASSERT_EQ(scan.exit_code, 0) << scan.err << daemon_->Log();
  const json started = json::parse(scan.out);
  const std::string id = started.at("id");
  EXPECT_EQ(started.at("state"), "done");
  EXPECT_GT(started.at("frames").get<int>(), 10);

  const CommandResult fetch = Run("device fetch " + id + " --json");
  ASSERT_EQ(fetch.exit_code, 0) << fetch.err;
  const fs::path stored = dir_ / "data" / (id + ".mscan");
  const std::string archive = ReadFile(dir_ / "host" / (id + ".mscan"));
  EXPECT_EQ(archive, ReadFile(stored));
  EXPECT_EQ(json::parse(fetch.out).at("sha256"), protocol::Sha256::HexOfFile(stored));
  const ScanArchive read = ReadScanFile(dir_ / "host" / (id + ".mscan"));
  EXPECT_TRUE(read.report.complete) << read.report.message;
  EXPECT_EQ(read.header.value("board", ""), "virtual");
  EXPECT_EQ(read.header.value("origin", ""), "api");
  // The upper and lower cameras saw the laser ring in every lit frame (the camera looking
  // up from 300 mm sees the lines only once they rise into its view, on the body from
  // about 600 mm: 23 of the 60 lit frames of this sweep once measured); the unlit ones
  // are those whose exposure began before the lasers went on (a camera's first, or a few
  // more when a loaded machine renders them late), never one after a lit frame.
  // And the peaks are the scene's stripes where the slide was (every third lit frame).
  const virtual_cabinet::Renderer renderer(
      virtual_cabinet::Scene::Load(kSource / "boards/virtual/scenes/mannequin.json"));
  std::map<int, int> lit, lit_with_peaks;
  test_support::PeakMatch match;
  std::map<int, int> unlit_after_lit;
  for (const FrameRecord& frame : read.frames) {
    if (!frame.lasers_on) {
      if (lit.count(frame.camera)) ++unlit_after_lit[frame.camera];
      continue;
    }
    if (lit[frame.camera]++ % 3 == 1)
      match += test_support::MatchFrameToScene(renderer, frame, 700.0, 2.0);
    if (!frame.peaks.empty()) ++lit_with_peaks[frame.camera];
  }
  EXPECT_EQ(lit.size(), 3u);
  EXPECT_EQ(lit_with_peaks[0], lit[0]);
  EXPECT_EQ(lit_with_peaks[1], lit[1]);
  EXPECT_GT(lit_with_peaks[2], lit[2] / 4);
  EXPECT_TRUE(unlit_after_lit.empty()) << unlit_after_lit.begin()->second << " unlit after lit";
  EXPECT_GE(lit[0] + lit[1] + lit[2], static_cast<int>(read.frames.size()) - 12);
  std::printf(
      "stored peaks vs the scene's truth: %zu of %zu found (RMS %.3f px), %zu of %zu false\n",
      match.found, match.truth, match.RmsPx(), match.false_peaks, match.peaks);
  EXPECT_GT(match.Recall(), 0.97);
  EXPECT_LT(match.RmsPx(), 0.5);
  EXPECT_LT(match.false_peaks, 0.02 * match.peaks);

  // A second scan streamed live while it runs equals the finished archive.
  const CommandResult follow = Run("device scan --follow --json --out live.mscan");
  ASSERT_EQ(follow.exit_code, 0) << follow.err;
  const std::string live_id = json::parse(follow.out).at("id");
  EXPECT_NE(live_id, id);
  EXPECT_EQ(ReadFile(dir_ / "host" / "live.mscan"), ReadFile(dir_ / "data" / (live_id + ".mscan")));

  const CommandResult list = Run("device list --json");
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_EQ(json::parse(list.out).size(), 2u);
}

}  // namespace
}  // namespace mirrorscan

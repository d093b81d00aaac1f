// mirrorscand as a process: a virtual scan from the start hook and from a (SIGUSR1)
// button press, SIGTERM and SIGKILL mid-sweep, a full disk (RLIMIT_FSIZE), and a drive
// fault and a camera stall injected on the virtual board (SIGUSR2). The crash tests use
// replay cameras (fast start-up); the scans use the rendered cabinet. "Lasers off" is
// read on the virtual laser lines (--line-state), as a probe on the pins would see it.

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/scan_format/scan_format.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"
#include "firmware/hal/virtual/virtual_line_states.h"
#include "firmware/store/scan_store.h"
#include "tests/support/process.h"
#include "tests/support/scene_truth.h"
#include "tests/support/temp_dir.h"
#include "tests/support/virtual_board.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

// mirrorscand as a child process; a file size limit when fsize_limit > 0.
class Daemon : public test_support::ChildProcess {
 public:
  Daemon(const std::vector<std::string>& args, const fs::path& log, rlim_t fsize_limit = 0,
         const std::vector<std::pair<std::string, std::string>>& env = {})
      : ChildProcess(MIRRORSCAND_PATH, args, log, {env, fsize_limit}) {}
};

class MirrorscandTest : public ::testing::Test {
 protected:
  // The virtual board with a 300 mm sweep (2 s) and, if `replay`, replay cameras playing a
  // 160 x 120 stripe instead of the renderer.
  fs::path WriteBoard(bool replay, double sweep_end_mm = 500.0) {
    return test_support::WriteVirtualBoard(dir_.path(), sweep_end_mm, replay);
  }
  std::vector<std::string> Args(const fs::path& board) {
    // Port 0: the device API takes any free port, so parallel tests never collide.
    return {"--board", board.string(), "--data-dir", data_.string(), "--listen", "127.0.0.1:0"};
  }
  std::vector<store::ScanInfo> Scans() {
    return store::ScanStore::Open(data_)->List();  // Open also recovers what a crash left
  }
  // `args` with the virtual lines mirrored to lines_.
  std::vector<std::string> WithLines(std::vector<std::string> args) const {
    args.insert(args.end(), {"--line-state", lines_.string()});
    return args;
  }
  // The daemon's laser lines as the line state file shows them (none before it exists).
  std::vector<hal::VirtualLineStates::Observed> Lasers() const {
    std::vector<hal::VirtualLineStates::Observed> lasers;
    try {
      for (auto& line : hal::VirtualLineStates::Read(lines_)) {
        if (line.name.rfind("laser[", 0) == 0) lasers.push_back(std::move(line));
      }
    } catch (const hal::HardwareError&) {
    }
    return lasers;
  }
  // Whether all three laser lines (active high on the virtual board) show `high` before
  // `deadline` (false as soon as the daemon exits).
  bool WaitLasers(bool high, test_support::ChildProcess& daemon,
                  milliseconds deadline = seconds(60)) {
    const auto end = std::chrono::steady_clock::now() + deadline;
    while (std::chrono::steady_clock::now() < end) {
      const auto lasers = Lasers();
      if (lasers.size() == 3 && std::all_of(lasers.begin(), lasers.end(),
                                            [&](const auto& l) { return l.high == high; })) {
        return true;
      }
      if (daemon.Exited()) return false;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    return false;
  }
  // Every laser line is low and went on and off exactly once; returns when the last went
  // off (steady ns, the same clock in every process).
  int64_t ExpectLasersWentOnAndOffOnce() {
    const auto lasers = Lasers();
    EXPECT_EQ(lasers.size(), 3u);
    int64_t off_ns = 0;
    for (const auto& laser : lasers) {
      EXPECT_FALSE(laser.high) << laser.name;
      EXPECT_EQ(laser.changes, 2u) << laser.name;
      off_ns = std::max(off_ns, laser.last_change_ns);
    }
    return off_ns;
  }

  // A scan on replay cameras with `fault` injected by SIGUSR2 0.3 s after the laser lines
  // went on, after an earlier complete scan. Checks the lines, the exit, and that the
  // earlier scan is byte for byte intact; returns the faulted scan's record and how long
  // after the injection the last laser line went low.
  std::pair<store::ScanInfo, int64_t> ScanWithInjectedFault(const std::string& fault) {
    const fs::path board = WriteBoard(true);
    std::vector<std::string> args = Args(board);
    args.insert(args.end(), {"--scan-on-start", "--exit-after-scan"});
    {
      Daemon first(args, dir_ / "log1");
      EXPECT_EQ(first.Wait(), 0) << first.Log();
    }
    const std::vector<store::ScanInfo> before = Scans();
    EXPECT_EQ(before.size(), 1u);
    if (before.size() != 1) return {};
    const std::string earlier_bytes = test_support::ReadFile(data_ / (before[0].id + ".mscan"));

    args = WithLines(args);
    args.insert(args.end(), {"--fault-on-sigusr2", fault});
    Daemon daemon(args, dir_ / "log2");
    EXPECT_TRUE(WaitLasers(true, daemon)) << daemon.Log();
    std::this_thread::sleep_for(milliseconds(300));  // 45 mm into the sweep
    const int64_t injected_ns = hal::SteadyNowNs();
    daemon.Signal(SIGUSR2);
    EXPECT_TRUE(WaitLasers(false, daemon, seconds(5))) << daemon.Log();
    const int64_t off_ns = ExpectLasersWentOnAndOffOnce() - injected_ns;
    EXPECT_EQ(daemon.Wait(), 1) << daemon.Log();  // the scan ended in a fault

    const std::vector<store::ScanInfo> after = Scans();
    EXPECT_EQ(after.size(), 2u);
    if (after.size() != 2) return {};
    EXPECT_EQ(after[1].id, before[0].id);
    EXPECT_EQ(after[1].state, store::ScanState::kComplete);
    EXPECT_EQ(after[1].frames, before[0].frames);
    EXPECT_EQ(test_support::ReadFile(data_ / (before[0].id + ".mscan")), earlier_bytes);
    EXPECT_EQ(after[0].state, store::ScanState::kFault) << after[0].reason;
    const ScanArchive archive = ReadScanFile(data_ / (after[0].id + ".mscan"));
    EXPECT_TRUE(archive.report.complete) << archive.report.message;
    EXPECT_GT(archive.frames.size(), 10u);
    if (archive.footer) {
      EXPECT_EQ((*archive.footer)["status"], "fault");
    } else {
      ADD_FAILURE() << "no footer";
    }
    return {after[0], off_ns};
  }

  const test_support::TempDir dir_{"mirrorscand_test"};
  const fs::path data_ = dir_ / "data";
  const fs::path lines_ = dir_ / "lines";
};

TEST_F(MirrorscandTest, VirtualScanFromTheStartHookStoresEveryFrame) {
  std::vector<std::string> args = WithLines(Args(WriteBoard(false)));
  args.insert(args.end(), {"--scan-on-start", "--exit-after-scan"});
  Daemon daemon(args, dir_ / "log");
  ASSERT_EQ(daemon.Wait(seconds(90)), 0) << daemon.Log();
  ExpectLasersWentOnAndOffOnce();
  const std::vector<store::ScanInfo> scans = Scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, store::ScanState::kComplete);
  const ScanArchive archive = ReadScanFile(data_ / (scans[0].id + ".mscan"));
  ASSERT_TRUE(archive.report.complete) << archive.report.message;
  EXPECT_EQ(archive.header["board"], "virtual");
  EXPECT_EQ(archive.header["origin"], "test");
  // Nothing dropped: no frame lost between the cameras and the archive, and each camera's
  // sequence without gaps. (How many frames a camera makes depends on how fast this
  // machine renders them: 30 fps x 2 s when idle, fewer under load.)
  EXPECT_EQ((*archive.footer)["dropped"], 0) << archive.footer->dump();
  const virtual_cabinet::Renderer renderer(
      virtual_cabinet::Scene::Load(kSource / "boards" / "virtual" / "scenes" / "mannequin.json"));
  test_support::PeakMatch match;
  for (int camera = 0; camera < 2; ++camera) {
    std::vector<const FrameRecord*> frames;
    for (const FrameRecord& f : archive.frames) {
      if (f.camera == camera) frames.push_back(&f);
    }
    ASSERT_GE(frames.size(), 20u) << "camera " << camera;
    EXPECT_EQ((*archive.footer)["frames"][camera], frames.size());
    for (size_t i = 0; i < frames.size(); ++i) {
      const FrameRecord& f = *frames[i];
      if (i > 0) {
        EXPECT_EQ(f.sequence, frames[i - 1]->sequence + 1) << "camera " << camera;
      }
      EXPECT_GE(f.slide_position_mm, 199.0);
      EXPECT_LE(f.slide_position_mm, 501.0);
      // Lit frames show the laser ring (on the mannequin and the panels). Only frames
      // whose exposure began before the lasers went on are recorded as off: the first
      // one, or a few more when a loaded machine renders them late; never one after a
      // lit frame.
      if (f.lasers_on) {
        EXPECT_FALSE(f.peaks.empty()) << "camera " << camera << " sequence " << f.sequence;
        if (i % 4 == 1) match += test_support::MatchFrameToScene(renderer, f, 200.0, 2.0);
      } else {
        EXPECT_TRUE(i == 0 || !frames[i - 1]->lasers_on)
            << "camera " << camera << " sequence " << f.sequence << ": unlit after a lit frame";
      }
    }
  }
  // The stored peaks are the scene's stripes where the slide was.
  std::printf(
      "stored peaks vs the scene's truth: %zu of %zu found (RMS %.3f px), %zu of %zu false\n",
      match.found, match.truth, match.RmsPx(), match.false_peaks, match.peaks);
  // Measured: 99.4 % found, RMS 0.075 px, 0.4 % false. The readback the truth is taken
  // at lags the slide by up to a poll period under load (~1 px), hence the RMS margin.
  EXPECT_GT(match.Recall(), 0.97);
  EXPECT_LT(match.RmsPx(), 0.5);
  EXPECT_LT(match.false_peaks, 0.02 * match.peaks);
}

TEST_F(MirrorscandTest, Sigusr1PressesTheVirtualButton) {
  std::vector<std::string> args = Args(WriteBoard(false));
  args.push_back("--exit-after-scan");
  Daemon daemon(args, dir_ / "log");
  ASSERT_TRUE(daemon.WaitLog("ready")) << daemon.Log();
  daemon.Signal(SIGUSR1);
  ASSERT_EQ(daemon.Wait(seconds(60)), 0) << daemon.Log();
  const std::vector<store::ScanInfo> scans = Scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, store::ScanState::kComplete);
  EXPECT_EQ(scans[0].header["origin"], "button");
}

TEST_F(MirrorscandTest, SigtermMidSweepAbortsTheScan) {
  std::vector<std::string> args = WithLines(Args(WriteBoard(true)));
  args.push_back("--scan-on-start");
  Daemon daemon(args, dir_ / "log");
  ASSERT_TRUE(WaitLasers(true, daemon)) << daemon.Log();
  std::this_thread::sleep_for(milliseconds(300));
  const int64_t signalled_ns = hal::SteadyNowNs();
  daemon.Signal(SIGTERM);
  ASSERT_EQ(daemon.Wait(), 0) << daemon.Log();
  const int64_t off_ns = ExpectLasersWentOnAndOffOnce() - signalled_ns;
  std::printf("SIGTERM -> laser lines low: %.1f ms\n", off_ns * 1e-6);
  EXPECT_LE(off_ns, 50'000'000);
  const std::vector<store::ScanInfo> scans = Scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, store::ScanState::kAborted);
  EXPECT_EQ(scans[0].reason, "SIGTERM");
  EXPECT_GT(scans[0].frames, 0u);
}

TEST_F(MirrorscandTest, SigkillMidSweepKeepsEarlierScansAndAReadablePrefix) {
  const fs::path board = WriteBoard(true);
  std::vector<std::string> args = Args(board);
  args.insert(args.end(), {"--scan-on-start", "--exit-after-scan"});
  {
    Daemon first(args, dir_ / "log1");
    ASSERT_EQ(first.Wait(), 0) << first.Log();
  }
  const std::vector<store::ScanInfo> before = Scans();
  ASSERT_EQ(before.size(), 1u);
  {
    Daemon killed(args, dir_ / "log2");
    ASSERT_TRUE(killed.WaitLog("sweeping")) << killed.Log();
    std::this_thread::sleep_for(milliseconds(700));
    killed.Signal(SIGKILL);
    ASSERT_EQ(killed.Wait(), 128 + SIGKILL);
  }
  // A restart finds both: the earlier one intact, the killed one partial.
  {
    Daemon restarted(Args(board), dir_ / "log3");
    ASSERT_TRUE(restarted.WaitLog("ready")) << restarted.Log();
    restarted.Signal(SIGTERM);
    ASSERT_EQ(restarted.Wait(), 0) << restarted.Log();
  }
  const std::vector<store::ScanInfo> after = Scans();
  ASSERT_EQ(after.size(), 2u);
  const store::ScanInfo& killed = after[0];  // newest first
  const store::ScanInfo& earlier = after[1];
  EXPECT_EQ(earlier.id, before[0].id);
  EXPECT_EQ(earlier.state, store::ScanState::kComplete);
  EXPECT_EQ(earlier.frames, before[0].frames);
  EXPECT_TRUE(ReadScanFile(data_ / (earlier.id + ".mscan")).report.complete);
  EXPECT_EQ(killed.state, store::ScanState::kPartial) << killed.reason;
  const ScanArchive prefix = ReadScanFile(data_ / (killed.id + ".mscan.partial"));
  EXPECT_FALSE(prefix.report.complete);
  EXPECT_GT(prefix.frames.size(), 10u) << prefix.report.message;
  EXPECT_EQ(prefix.header["scan_id"], killed.id);
}

TEST_F(MirrorscandTest, DiskFullIsACleanFault) {
  const fs::path board = WriteBoard(true);
  std::vector<std::string> args = Args(board);
  args.insert(args.end(), {"--scan-on-start", "--exit-after-scan"});
  {
    Daemon first(args, dir_ / "log1");
    ASSERT_EQ(first.Wait(), 0) << first.Log();
  }
  const std::vector<store::ScanInfo> before = Scans();
  ASSERT_EQ(before.size(), 1u);
  Daemon full(WithLines(args), dir_ / "log2", 64 * 1024);
  ASSERT_EQ(full.Wait(), 1) << full.Log();  // the scan ended in a fault
  const std::string log = full.Log();
  EXPECT_NE(log.find("scan store"), std::string::npos) << log;
  ExpectLasersWentOnAndOffOnce();
  const std::vector<store::ScanInfo> after = Scans();
  ASSERT_EQ(after.size(), 2u);
  EXPECT_EQ(after[1].id, before[0].id);
  EXPECT_EQ(after[1].state, store::ScanState::kComplete);
  EXPECT_EQ(after[1].frames, before[0].frames);
  EXPECT_EQ(after[0].state, store::ScanState::kPartial);
  EXPECT_GT(ReadScanFile(data_ / (after[0].id + ".mscan.partial")).frames.size(), 0u);
}

TEST_F(MirrorscandTest, DriveFaultMidSweepDarkensTheLaserLinesAndKeepsEarlierScans) {
  const auto [scan, off_ns] = ScanWithInjectedFault("drive-fault");
  std::printf("drive fault -> laser lines low: %.1f ms\n", off_ns * 1e-6);
  EXPECT_GT(off_ns, 0);
  EXPECT_LE(off_ns, 50'000'000);
  EXPECT_EQ(scan.reason, "drive fault 66");
}

TEST_F(MirrorscandTest, CameraStallMidSweepDarkensTheLaserLinesAndKeepsEarlierScans) {
  const auto [scan, off_ns] = ScanWithInjectedFault("camera-stall:lower");
  std::printf("camera stall -> laser lines low: %.1f ms\n", off_ns * 1e-6);
  // Known only after scan.camera_stall_ms (250) since the camera's last frame, which came
  // at most a frame period (33 ms) before the stall.
  EXPECT_GE(off_ns, 250'000'000 - 34'000'000);
  EXPECT_LE(off_ns, 250'000'000 + 50'000'000);
  EXPECT_NE(scan.reason.find("camera lower stalled"), std::string::npos) << scan.reason;
}

TEST_F(MirrorscandTest, NotifiesSystemdReadyWatchdogAndStopping) {
  const fs::path socket_path = dir_ / "notify";
  const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::strncpy(address.sun_path, socket_path.c_str(), sizeof(address.sun_path) - 1);
  ASSERT_EQ(bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
  timeval timeout{0, 100000};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  Daemon daemon(Args(WriteBoard(true)), dir_ / "log", 0,
                {{"NOTIFY_SOCKET", socket_path.string()}, {"WATCHDOG_USEC", "200000"}});
  std::vector<std::string> messages;
  const auto end = std::chrono::steady_clock::now() + seconds(30);
  auto count = [&](const std::string& m) {
    return std::count(messages.begin(), messages.end(), m);
  };
  while (std::chrono::steady_clock::now() < end && count("STOPPING=1") == 0) {
    char buffer[256];
    const ssize_t n = recv(fd, buffer, sizeof buffer, 0);
    if (n > 0) messages.emplace_back(buffer, static_cast<size_t>(n));
    if (count("WATCHDOG=1") == 3) daemon.Signal(SIGTERM);
  }
  close(fd);
  EXPECT_EQ(daemon.Wait(), 0) << daemon.Log();
  ASSERT_FALSE(messages.empty());
  EXPECT_EQ(messages.front(), "READY=1");
  EXPECT_GE(count("WATCHDOG=1"), 3);
  EXPECT_EQ(count("STOPPING=1"), 1);
}

// A stored calibration that no longer validates does not keep the device from starting
// (it could then never be given a new one): it is set aside, the log says why.
TEST_F(MirrorscandTest, InvalidStoredCalibrationIsSetAsideAndTheDeviceStarts) {
  fs::create_directories(data_);
  std::ofstream(data_ / "calibration.json") << R"({"schema": "mirrorscan.calibration"})";
  Daemon daemon(Args(WriteBoard(true)), dir_ / "log");
  ASSERT_TRUE(daemon.WaitLog("ready")) << daemon.Log();
  EXPECT_NE(daemon.Log().find("calibration.json.invalid); the device runs uncalibrated"),
            std::string::npos)
      << daemon.Log();
  EXPECT_FALSE(fs::exists(data_ / "calibration.json"));
  EXPECT_TRUE(fs::exists(data_ / "calibration.json.invalid"));
  daemon.Signal(SIGTERM);
  EXPECT_EQ(daemon.Wait(), 0) << daemon.Log();
}

TEST_F(MirrorscandTest, BadInputGetsOneLineAndItsExitCode) {
  Daemon no_args({"--board"}, dir_ / "log1");
  EXPECT_EQ(no_args.Wait(), 2);
  EXPECT_NE(no_args.Log().find("--board needs a value"), std::string::npos);
  Daemon missing({"--board", (dir_ / "none.json").string(), "--data-dir", data_.string()},
                 dir_ / "log2");
  EXPECT_EQ(missing.Wait(), 2);
  EXPECT_NE(missing.Log().find("none.json"), std::string::npos);
}

}  // namespace
}  // namespace mirrorscan

// The whole appliance on loopback: mirrorscand on the virtual board (rendered cameras,
// simulated drive over Modbus, virtual GPIO, the real sequencer, store and API), driven by the
// `mirrorscan device` CLI: a scan started and followed to its end, the archive fetched and
// compared byte for byte with the store's file, and a live --follow of a second scan.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"

extern char** environ;

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A loopback port nobody listens on right now.
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

struct CliResult {
  int exit_code;
  std::string out;
  std::string err;
};

class DeviceEndToEndTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/device_e2e_test.XXXXXX";
    ASSERT_NE(::mkdtemp(pattern), nullptr);
    dir_ = pattern;
    fs::create_directories(dir_ / "host");
    token_ = json::parse(ReadFile(kSource / "boards/virtual/board.json"))["service"]["token"];
    host_ = "127.0.0.1:" + std::to_string(FreePort());
    const fs::path board = WriteBoard();
    std::vector<std::string> args = {
        MIRRORSCAND_PATH,         "--board",  board.string(), "--data-dir",
        (dir_ / "data").string(), "--listen", host_};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, (dir_ / "daemon.log").c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    ASSERT_EQ(posix_spawn(&daemon_, MIRRORSCAND_PATH, &actions, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    // Ready when the API answers.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (Run("device status").exit_code != 0) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << ReadFile(dir_ / "daemon.log");
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }

  void TearDown() override {
    if (daemon_ > 0) {
      ::kill(daemon_, SIGTERM);
      int status = 0;
      ::waitpid(daemon_, &status, 0);
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << ReadFile(dir_ / "daemon.log");
    }
    fs::remove_all(dir_);
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

  CliResult Run(const std::string& arguments) const {
    const fs::path err = dir_ / "stderr.txt";
    const std::string command =
        "cd " + (dir_ / "host").string() + " && MIRRORSCAN_TOKEN=" + token_ + " " +
        MIRRORSCAN_BIN_DIR + "/mirrorscan " + arguments + " --host " + host_ + " 2>" + err.string();
    FILE* pipe = ::popen(command.c_str(), "r");
    std::string out;
    std::array<char, 4096> buffer;
    while (size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe))
      out.append(buffer.data(), n);
    const int status = ::pclose(pipe);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out, ReadFile(err)};
  }

  fs::path dir_;
  std::string token_;
  std::string host_;
  pid_t daemon_ = -1;
};

TEST_F(DeviceEndToEndTest, ScanWaitFetchAndFollowMatchTheStoredArchive) {
  const CliResult scan = Run("device scan --wait --json");
  ASSERT_EQ(scan.exit_code, 0) << scan.err << ReadFile(dir_ / "daemon.log");
  const json started = json::parse(scan.out);
  const std::string id = started.at("id");
  EXPECT_EQ(started.at("state"), "done");
  EXPECT_GT(started.at("frames").get<int>(), 10);

  const CliResult fetch = Run("device fetch " + id + " --json");
  ASSERT_EQ(fetch.exit_code, 0) << fetch.err;
  const fs::path stored = dir_ / "data" / (id + ".mscan");
  const std::string archive = ReadFile(dir_ / "host" / (id + ".mscan"));
  EXPECT_EQ(archive, ReadFile(stored));
  EXPECT_EQ(json::parse(fetch.out).at("sha256"), protocol::Sha256::HexOfFile(stored));
  const ScanArchive read = ReadScanFile(dir_ / "host" / (id + ".mscan"));
  EXPECT_TRUE(read.report.complete) << read.report.message;
  EXPECT_EQ(read.header.value("board", ""), "virtual");
  EXPECT_EQ(read.header.value("origin", ""), "api");
  // Both cameras saw the laser ring on the mannequin in every frame.
  std::map<int, int> frames_with_peaks;
  for (const FrameRecord& frame : read.frames) {
    if (!frame.peaks.empty()) ++frames_with_peaks[frame.camera];
  }
  EXPECT_EQ(frames_with_peaks.size(), 2u);
  EXPECT_EQ(frames_with_peaks[0] + frames_with_peaks[1], static_cast<int>(read.frames.size()));

  // A second scan streamed live while it runs equals the finished archive.
  const CliResult follow = Run("device scan --follow --json --out live.mscan");
  ASSERT_EQ(follow.exit_code, 0) << follow.err;
  const std::string live_id = json::parse(follow.out).at("id");
  EXPECT_NE(live_id, id);
  EXPECT_EQ(ReadFile(dir_ / "host" / "live.mscan"), ReadFile(dir_ / "data" / (live_id + ".mscan")));

  const CliResult list = Run("device list --json");
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_EQ(json::parse(list.out).size(), 2u);
}

}  // namespace
}  // namespace mirrorscan

// The device API end to end on loopback: the real ApiServer and ScanStore (TestScanControl
// stands in for the sequencer), the host's DeviceClient and the `mirrorscan device` CLI.
// Downloads cut mid-way (TcpCutProxy) must resume to identical bytes; a followed stream
// must equal the finished archive; a corrupted download must be refused.

#include <atomic>
#include <fstream>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "host/client/device_client.h"
#include "tests/support/in_process_device.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/tcp_cut_proxy.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using client::DeviceClient;
using client::DeviceError;
using nlohmann::json;
using test_util::TcpCutProxy;

constexpr const char* kToken = test_support::kVirtualToken;
const fs::path kCalibration =
    fs::path(MIRRORSCAN_SOURCE_DIR) / "firmware/service/testdata/calibration.json";

using test_support::CommandResult;
using test_support::ReadFile;

class DeviceApiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dir_ / "host");
    test_support::InProcessDeviceOptions options;
    // ~0.9 MB archives, written over ~1 s, so cuts land mid-stream and follows see a live scan.
    options.scan = {
        .frames = 100, .frame_interval = std::chrono::milliseconds(10), .peaks_per_frame = 500};
    options.server.firmware_version = "test";
    device_ = std::make_unique<test_support::InProcessDevice>(dir_ / "device", options);
    store_ = device_->store.get();
    control_ = device_->control.get();
    port_ = device_->port;
  }

  std::string Host(int port = 0) const {
    return "127.0.0.1:" + std::to_string(port ? port : port_);
  }

  DeviceClient Client(int port = 0, const std::string& token = kToken) const {
    return DeviceClient(Host(port), token,
                        client::DeviceClientOptions{.retry_delay = std::chrono::milliseconds(20)});
  }

  std::string CompletedScan() {
    const std::string id = Client().StartScan();
    control_->Join();
    return id;
  }

  // Runs the CLI in dir_/host with `environment` prepended.
  CommandResult Run(const std::string& arguments, const std::string& environment = "") const {
    return test_support::RunCommand("cd " + (dir_ / "host").string() +
                                        " && env -u MIRRORSCAN_TOKEN " + environment + " " +
                                        MIRRORSCAN_BIN_DIR + "/mirrorscan " + arguments,
                                    dir_ / "stderr.txt");
  }

  const test_support::TempDir dir_{"mirrorscan_device_api_test"};
  std::unique_ptr<test_support::InProcessDevice> device_;
  store::ScanStore* store_ = nullptr;
  service::TestScanControl* control_ = nullptr;
  int port_ = 0;
};

TEST_F(DeviceApiTest, ClientCallsAndErrors) {
  DeviceClient device = Client();
  EXPECT_EQ(device.Status().board, "virtual");
  const std::string id = CompletedScan();
  const auto scans = device.List();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].id, id);
  EXPECT_EQ(device.Get(id).frames, 100u);

  const std::string calibration = ReadFile(kCalibration);
  const std::string sha = device.PutCalibration(calibration);
  EXPECT_EQ(device.GetCalibration(), calibration);
  EXPECT_EQ(device.Status().calibration_sha256, sha);
  const std::string pgm = device.Capture("upper", false);
  EXPECT_EQ(pgm.rfind("P5\n64 48\n255\n", 0), 0u);

  try {
    Client(0, "").Delete(id);
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.status(), 401);
    EXPECT_EQ(e.code(), "unauthorized");
    EXPECT_NE(std::string(e.what()).find("missing bearer token"), std::string::npos) << e.what();
  }
  try {
    device.Get("20991231T235959Z-9999");
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.status(), 404);
  }
  EXPECT_THROW(device.Get("../etc"), DeviceError);
  device.Delete(id);
  EXPECT_TRUE(device.List().empty());
}

TEST_F(DeviceApiTest, FetchResumesAfterDroppedConnectionsToIdenticalBytes) {
  const std::string id = CompletedScan();
  const std::string on_disk = ReadFile(store_->Path(id));
  ASSERT_GT(on_disk.size(), 500000u);
  // Cut the first two connections after 200 kB each (headers included).
  TcpCutProxy proxy(port_, 200000, 2);
  const fs::path out = dir_ / "host" / "scan.mscan";
  uint64_t last_progress = 0;
  const client::FetchResult r =
      Client(proxy.port()).Fetch(id, out, [&](const client::TransferProgress& p) {
        EXPECT_GE(p.bytes, last_progress > 0 && p.reconnects == 0 ? last_progress : 0u);
        last_progress = p.bytes;
        EXPECT_EQ(p.total, on_disk.size());
      });
  EXPECT_EQ(proxy.damaged(), 2);
  EXPECT_EQ(r.reconnects, 2);
  EXPECT_EQ(ReadFile(out), on_disk);
  EXPECT_EQ(r.sha256, protocol::Sha256::HexOfFile(store_->Path(id)));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
}

TEST_F(DeviceApiTest, FetchResumesAPartialFileFromAnEarlierRun) {
  const std::string id = CompletedScan();
  const std::string on_disk = ReadFile(store_->Path(id));
  const fs::path out = dir_ / "host" / "scan.mscan";
  std::ofstream(out.string() + ".partial", std::ios::binary) << on_disk.substr(0, 12345);
  uint64_t first_progress = 0;
  Client().Fetch(id, out, [&](const client::TransferProgress& p) {
    if (first_progress == 0) first_progress = p.bytes;
  });
  EXPECT_GT(first_progress, 12345u);  // it went on from there
  EXPECT_EQ(ReadFile(out), on_disk);
}

TEST_F(DeviceApiTest, CorruptedDownloadIsRefusedAndDiscarded) {
  const std::string id = CompletedScan();
  TcpCutProxy proxy(port_, 300000, 1, TcpCutProxy::Mode::kCorrupt);
  const fs::path out = dir_ / "host" / "scan.mscan";
  try {
    Client(proxy.port()).Fetch(id, out);
    FAIL() << "a corrupted download was accepted";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.code(), "checksum");
    EXPECT_NE(std::string(e.what()).find("SHA-256 mismatch"), std::string::npos) << e.what();
  }
  EXPECT_EQ(proxy.damaged(), 1);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
}

TEST_F(DeviceApiTest, FollowedStreamWithADropEqualsTheFinishedArchive) {
  const std::string id = Client().StartScan();
  TcpCutProxy proxy(port_, 150000, 1);
  DeviceClient device = Client(proxy.port());
  const fs::path out = dir_ / "host" / "live.mscan";
  uint64_t frames_while_running = 0;
  const client::FetchResult r = device.Follow(id, out, [&](const client::TransferProgress& p) {
    if (control_->Status().state == scan::SequencerState::kSweeping)
      frames_while_running = p.frames;
  });
  control_->Join();
  EXPECT_GT(frames_while_running, 0u) << "no frame arrived before the sweep ended";
  EXPECT_EQ(proxy.damaged(), 1);
  EXPECT_EQ(r.reconnects, 1);
  EXPECT_EQ(ReadFile(out), ReadFile(store_->Path(id)));
  const ScanArchive archive = ReadScanFile(out);
  EXPECT_TRUE(archive.report.complete) << archive.report.message;
  EXPECT_EQ(archive.frames.size(), 100u);
}

TEST_F(DeviceApiTest, CliScanWaitThenFetchGivesTheArchiveByteForByte) {
  const CommandResult scan =
      Run("device scan --wait --json --host " + Host() + " --token " + kToken);
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const json started = json::parse(scan.out);
  const std::string id = started.at("id");
  EXPECT_EQ(started.at("state"), "done");
  EXPECT_EQ(started.at("frames"), 100);

  const CommandResult list = Run("device list --json --host " + Host() + " --token " + kToken);
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_EQ(json::parse(list.out).at(0).at("id"), id);

  // Through a proxy that drops the first connection: resumed, verified, ID.mscan here.
  TcpCutProxy proxy(port_, 100000, 1);
  const CommandResult fetch =
      Run("device fetch " + id + " --host " + Host(proxy.port()) + " --token " + kToken);
  ASSERT_EQ(fetch.exit_code, 0) << fetch.err;
  EXPECT_NE(fetch.err.find("verified, resumed 1x"), std::string::npos) << fetch.err;
  EXPECT_EQ(ReadFile(dir_ / "host" / (id + ".mscan")), ReadFile(store_->Path(id)));

  const CommandResult status = Run("device status --host " + Host());
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_NE(status.out.find("board virtual"), std::string::npos) << status.out;
  EXPECT_NE(status.out.find("done"), std::string::npos) << status.out;
}

TEST_F(DeviceApiTest, CliScanWaitPollsWhenEveryStreamSlotIsTaken) {
  // Four event streams (the server's limit) held by other clients.
  std::atomic<bool> release{false};
  std::atomic<int> holding{0};
  std::vector<std::thread> holders;
  for (int i = 0; i < 4; ++i) {
    holders.emplace_back([&] {
      DeviceClient client = Client();
      bool counted = false;
      client.Events([&](const protocol::ScanEventMessage&) {
        if (!counted) ++holding;
        counted = true;
        return !release;
      });
    });
  }
  for (int i = 0; i < 500 && holding < 4; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(holding, 4);
  const CommandResult scan =
      Run("device scan --wait --json --host " + Host() + " --token " + kToken);
  EXPECT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_EQ(json::parse(scan.out).value("state", ""), "done") << scan.out;
  release = true;
  CompletedScan();  // its events let the holders see `release`
  for (auto& t : holders) t.join();
}

TEST_F(DeviceApiTest, CliAbortStopsTheRunningScan) {
  const std::string id = Client().StartScan();
  const CommandResult abort = Run("device abort --json --host " + Host() + " --token " + kToken);
  ASSERT_EQ(abort.exit_code, 0) << abort.err;
  EXPECT_EQ(json::parse(abort.out).value("aborted", ""), id);
  control_->Join();
  EXPECT_EQ(store_->Get(id).state, store::ScanState::kAborted);
  const CommandResult again = Run("device abort --host " + Host() + " --token " + kToken);
  EXPECT_NE(again.exit_code, 0);
  EXPECT_NE(again.err.find("no scan is running"), std::string::npos) << again.err;
  const CommandResult denied = Run("device abort --host " + Host());
  EXPECT_NE(denied.exit_code, 0);
}

TEST_F(DeviceApiTest, CliScanFollowStreamsTheArchiveLive) {
  const CommandResult scan = Run("device scan --follow --json --out live.mscan --host " + Host(),
                                 std::string("MIRRORSCAN_TOKEN=") + kToken);
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const json result = json::parse(scan.out);
  const std::string id = result.at("id");
  EXPECT_EQ(result.at("state"), "complete");
  EXPECT_EQ(ReadFile(dir_ / "host" / "live.mscan"), ReadFile(store_->Path(id)));
  EXPECT_EQ(result.at("sha256"), protocol::Sha256::HexOfFile(store_->Path(id)));
}

TEST_F(DeviceApiTest, CliRefusesWithoutTokenAndExplains) {
  const std::string id = CompletedScan();
  const CommandResult denied = Run("device delete " + id + " --host " + Host());
  EXPECT_EQ(denied.exit_code, 1);
  EXPECT_NE(denied.err.find("missing bearer token"), std::string::npos) << denied.err;
  EXPECT_NE(denied.err.find("401"), std::string::npos) << denied.err;
  const CommandResult wrong =
      Run("device delete " + id + " --host " + Host() + " --token wrong-token-0123456789");
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_NE(wrong.err.find("wrong bearer token"), std::string::npos) << wrong.err;
  EXPECT_EQ(store_->List().size(), 1u);
  const CommandResult deleted =
      Run("device delete " + id + " --host " + Host(), std::string("MIRRORSCAN_TOKEN=") + kToken);
  EXPECT_EQ(deleted.exit_code, 0) << deleted.err;
  EXPECT_TRUE(store_->List().empty());

  const CommandResult unreachable = Run("device status --host 127.0.0.1:1");
  EXPECT_EQ(unreachable.exit_code, 1);
  EXPECT_NE(unreachable.err.find("cannot reach the device at 127.0.0.1:1"), std::string::npos)
      << unreachable.err;
  const CommandResult bad_id = Run("device fetch ../../etc/passwd --host " + Host());
  EXPECT_EQ(bad_id.exit_code, 1);
  EXPECT_NE(bad_id.err.find("not a scan id"), std::string::npos) << bad_id.err;
}

TEST_F(DeviceApiTest, CliCalibrationAndCapture) {
  const fs::path calibration = dir_ / "host" / "calibration.json";
  json one_mirror = json::parse(ReadFile(kCalibration));
  one_mirror["mirrors"].erase(1);
  std::ofstream(calibration) << one_mirror.dump();
  const std::string auth = std::string("MIRRORSCAN_TOKEN=") + kToken;
  const CommandResult refused =
      Run("device calibration put calibration.json --host " + Host(), auth);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("mirrors: expected two mirrors"), std::string::npos) << refused.err;
  fs::copy_file(kCalibration, calibration, fs::copy_options::overwrite_existing);
  const CommandResult put =
      Run("device calibration put calibration.json --json --host " + Host(), auth);
  ASSERT_EQ(put.exit_code, 0) << put.err;
  EXPECT_EQ(json::parse(put.out).at("sha256"), protocol::Sha256::HexOfFile(calibration));
  const CommandResult get =
      Run("device calibration get --out back.json --host " + Host() + " --token " + kToken);
  ASSERT_EQ(get.exit_code, 0) << get.err;
  EXPECT_EQ(ReadFile(dir_ / "host" / "back.json"), ReadFile(calibration));

  const CommandResult capture =
      Run("device capture --camera upper --lasers --host " + Host(), auth);
  ASSERT_EQ(capture.exit_code, 0) << capture.err;
  EXPECT_EQ(ReadFile(dir_ / "host" / "upper-lasers.pgm").rfind("P5\n64 48\n255\n", 0), 0u);
}

TEST_F(DeviceApiTest, HelpNamesEverySubcommand) {
  const CommandResult help = Run("device --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* sub : {"status", "list", "scan", "fetch", "delete", "calibration", "capture",
                          "discover", "--host", "--token", "MIRRORSCAN_TOKEN", "--json"}) {
    EXPECT_NE(help.out.find(sub), std::string::npos) << sub;
  }
  for (const char* sub : {"status", "list", "scan", "fetch", "delete", "calibration get",
                          "calibration put", "capture", "discover"}) {
    const CommandResult h = Run(std::string("device ") + sub + " --help");
    EXPECT_EQ(h.exit_code, 0) << sub;
    EXPECT_NE(h.out.find("Usage:"), std::string::npos) << sub;
  }
}

}  // namespace
}  // namespace mirrorscan

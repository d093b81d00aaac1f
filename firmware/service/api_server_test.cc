#include "firmware/service/api_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <httplib.h>

#include "common/protocol/protocol.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "tests/support/in_process_device.h"
#include "tests/support/loopback.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kToken = test_support::kVirtualToken;
using test_support::ExpectJsonError;
using test_support::ReadFile;

std::string Sha256Of(const std::string& bytes) {
  protocol::Sha256 sha;
  sha.Update(bytes);
  return sha.HexDigest();
}

class ApiServerTest : public ::testing::Test {
 protected:
  void SetUp() override { Start({}); }

  // A new device in a new folder (dir_/device<n>).
  void Start(TestScanControl::Options scan_options, bool auth_reads = false) {
    device_.reset();
    test_support::InProcessDeviceOptions options;
    options.scan = scan_options;
    options.auth_reads = auth_reads;
    options.server.firmware_version = "9.8.7";
    options.server.connections = limits_;
    options.server.connections.write_timeout = io_timeout_;
    // A keep-alive line is how a vanished SSE client is noticed; short here so tests are.
    options.server.keepalive_interval = std::chrono::milliseconds(200);
    device_dir_ = dir_ / ("device" + std::to_string(starts_++));
    device_ = std::make_unique<test_support::InProcessDevice>(device_dir_, options);
    store_ = device_->store.get();
    control_ = device_->control.get();
    calibration_ = device_->calibration.get();
    server_ = device_->server.get();
    port_ = device_->port;
  }

  httplib::Client Client() const { return device_->Client(); }
  httplib::Headers Auth(const std::string& token = kToken) const {
    return test_support::BearerAuth(token);
  }

  // Starts a scan through the API and returns its id.
  std::string StartScan() {
    auto res = Client().Post("/api/v1/scans", Auth(), "", "application/json");
    EXPECT_TRUE(res);
    if (!res) return "";
    EXPECT_EQ(res->status, 201) << res->body;
    return json::parse(res->body).at("id").get<std::string>();
  }

  std::string CompletedScan() {
    const std::string id = StartScan();
    control_->Join();
    return id;
  }

  const test_support::TempDir dir_{"api_server_test"};
  int starts_ = 0;
  fs::path device_dir_;
  std::unique_ptr<test_support::InProcessDevice> device_;
  store::ScanStore* store_ = nullptr;
  TestScanControl* control_ = nullptr;
  CalibrationStore* calibration_ = nullptr;
  ApiServer* server_ = nullptr;
  int port_ = 0;
  std::chrono::milliseconds io_timeout_{2000};
  ConnectionLimits limits_;
};

TEST_F(ApiServerTest, StatusNamesBoardVersionStateAndDisk) {
  auto res = Client().Get("/api/v1/status");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("X-Mirrorscan-Api-Version"), "1");
  const auto status = json::parse(res->body).get<protocol::DeviceStatus>();
  EXPECT_EQ(status.board, "virtual");
  EXPECT_EQ(status.firmware_version, "9.8.7");
  EXPECT_EQ(status.scan.state, "idle");
  EXPECT_EQ(status.calibration_sha256, "");
  EXPECT_GT(status.disk.total_bytes, 0u);
  EXPECT_EQ(status.disk.scans_bytes, 0u);
}

TEST_F(ApiServerTest, ScanIsListedAndItsArchiveDownloadsWithChecksum) {
  const std::string id = CompletedScan();
  const std::string on_disk = ReadFile(store_->Path(id));
  ASSERT_GT(on_disk.size(), 1000u);

  auto list = Client().Get("/api/v1/scans");
  ASSERT_TRUE(list);
  const json scans = json::parse(list->body).at("scans");
  ASSERT_EQ(scans.size(), 1u);
  const auto summary = scans[0].get<protocol::ScanSummary>();
  EXPECT_EQ(summary.id, id);
  EXPECT_EQ(summary.state, "complete");
  EXPECT_EQ(summary.frames, 40u);
  EXPECT_EQ(summary.bytes, on_disk.size());

  auto one = Client().Get("/api/v1/scans/" + id);
  ASSERT_TRUE(one);
  EXPECT_EQ(json::parse(one->body).get<protocol::ScanSummary>().header.value("origin", ""), "api");

  auto archive = Client().Get("/api/v1/scans/" + id + "/archive");
  ASSERT_TRUE(archive);
  EXPECT_EQ(archive->status, 200);
  EXPECT_EQ(archive->body, on_disk);
  EXPECT_EQ(archive->get_header_value("X-Mirrorscan-SHA256"), Sha256Of(on_disk));
  EXPECT_EQ(archive->get_header_value("ETag"), "\"" + Sha256Of(on_disk) + "\"");
  EXPECT_EQ(archive->get_header_value("Accept-Ranges"), "bytes");
  const ScanArchive read = ReadScan(
      std::span(reinterpret_cast<const uint8_t*>(archive->body.data()), archive->body.size()));
  EXPECT_TRUE(read.report.complete) << read.report.message;
  EXPECT_EQ(read.frames.size(), 40u);
}

TEST_F(ApiServerTest, RangesResumeAndBadRangesGet416) {
  const std::string id = CompletedScan();
  const std::string on_disk = ReadFile(store_->Path(id));
  const std::string path = "/api/v1/scans/" + id + "/archive";
  const size_t size = on_disk.size();

  auto tail = Client().Get(path, {{"Range", "bytes=1000-"}});
  ASSERT_TRUE(tail);
  EXPECT_EQ(tail->status, 206);
  EXPECT_EQ(tail->body, on_disk.substr(1000));
  EXPECT_EQ(tail->get_header_value("Content-Range"),
            "bytes 1000-" + std::to_string(size - 1) + "/" + std::to_string(size));
  EXPECT_EQ(tail->get_header_value("X-Mirrorscan-SHA256"), Sha256Of(on_disk));

  auto middle = Client().Get(path, {{"Range", "bytes=10-19"}});
  ASSERT_TRUE(middle);
  EXPECT_EQ(middle->status, 206);
  EXPECT_EQ(middle->body, on_disk.substr(10, 10));

  auto suffix = Client().Get(path, {{"Range", "bytes=-7"}});
  ASSERT_TRUE(suffix);
  EXPECT_EQ(suffix->body, on_disk.substr(size - 7));

  for (const std::string& bad :
       std::vector<std::string>{"bytes=" + std::to_string(size) + "-", "bytes=0-1,4-5", "bytes=9-3",
                                "items=0-", "bytes=-0"}) {
    SCOPED_TRACE(bad);
    auto res = Client().Get(path, {{"Range", bad}});
    ExpectJsonError(res, 416, "Range");
    // httplib itself refuses syntax errors, before the archive's size is known.
    if (bad.find("bytes=9-3") == std::string::npos && bad.find("items") == std::string::npos) {
      EXPECT_EQ(res->get_header_value("Content-Range"), "bytes */" + std::to_string(size));
    }
  }
  // A Range header on a JSON endpoint is ignored, never cuts the body.
  auto status = Client().Get("/api/v1/status", {{"Range", "bytes=5-"}});
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  EXPECT_TRUE(json::parse(status->body, nullptr, false).is_object());
}

TEST_F(ApiServerTest, FollowStreamsTheRunningScanUpToTheFooter) {
  Start({.frames = 60, .frame_interval = std::chrono::milliseconds(15), .peaks_per_frame = 100});
  const std::string id = StartScan();
  // A plain download of a scan being written is refused and says what to do.
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/archive"), 409, "follow=1");

  std::string streamed;
  bool bytes_before_end = false;
  auto res = Client().Get("/api/v1/scans/" + id + "/archive?follow=1",
                          [&](const char* data, size_t length) {
                            streamed.append(data, length);
                            if (control_->Status().state == scan::SequencerState::kSweeping) {
                              bytes_before_end = true;
                            }
                            return true;
                          });
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_TRUE(bytes_before_end) << "nothing arrived while the scan ran";
  control_->Join();
  const std::string on_disk = ReadFile(store_->Path(id));
  EXPECT_EQ(store_->Get(id).state, store::ScanState::kComplete);
  EXPECT_EQ(streamed, on_disk);
  const ScanArchive read =
      ReadScan(std::span(reinterpret_cast<const uint8_t*>(streamed.data()), streamed.size()));
  EXPECT_TRUE(read.report.complete) << read.report.message;
  EXPECT_EQ(read.frames.size(), 60u);
}

// Opens a follow of `id` on a raw socket with a tiny receive buffer and never reads it.
int StalledFollower(int port, const std::string& id) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  const int small = 4096;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof(small));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) return -1;
  const std::string request =
      "GET /api/v1/scans/" + id + "/archive?follow=1 HTTP/1.1\r\nHost: x\r\n\r\n";
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  return fd;
}

TEST_F(ApiServerTest, ReadersThatStallNeverSlowTheScan) {
  // Stalled clients would hold their streams for a minute; a scan that waited for them
  // would take that long.
  io_timeout_ = std::chrono::seconds(60);
  Start({.frames = 100, .frame_interval = std::chrono::milliseconds(10), .peaks_per_frame = 3500});
  const auto start = std::chrono::steady_clock::now();
  const std::string id = StartScan();
  std::vector<int> stalled;
  for (int i = 0; i < 3; ++i) stalled.push_back(StalledFollower(port_, id));
  auto status = Client().Get("/api/v1/status");  // still served meanwhile
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  control_->Join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // 100 frames x 10 ms; the ~6 MB archive is more than loopback socket buffers hold (4 MB
  // at most), so the stalled streams really block their server threads.
  EXPECT_GT(fs::file_size(store_->Path(id)), 5'000'000u);
  EXPECT_LT(seconds, 30.0);  // about 1 s; generous for qemu
  EXPECT_EQ(store_->Get(id).state, store::ScanState::kComplete);
  for (const int fd : stalled) ::close(fd);
}

TEST_F(ApiServerTest, FollowResumesFromAnOffset) {
  Start({.frames = 30, .frame_interval = std::chrono::milliseconds(10), .peaks_per_frame = 50});
  const std::string id = StartScan();
  std::string streamed;
  auto res = Client().Get("/api/v1/scans/" + id + "/archive?follow=1&offset=100",
                          [&](const char* data, size_t length) {
                            streamed.append(data, length);
                            return true;
                          });
  ASSERT_TRUE(res);
  control_->Join();
  EXPECT_EQ(streamed, ReadFile(store_->Path(id)).substr(100));
  // Following a finished scan past its end is refused; at its end yields nothing.
  const size_t size = fs::file_size(store_->Path(id));
  ExpectJsonError(
      Client().Get("/api/v1/scans/" + id + "/archive?follow=1&offset=" + std::to_string(size + 1)),
      416, "past the end");
  auto at_end =
      Client().Get("/api/v1/scans/" + id + "/archive?follow=1&offset=" + std::to_string(size));
  ASSERT_TRUE(at_end);
  EXPECT_EQ(at_end->status, 200);
  EXPECT_EQ(at_end->body, "");
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/archive?follow=1&offset=-1"), 400,
                  "offset");
}

TEST_F(ApiServerTest, EventsReportStateAndProgressThenUnsubscribe) {
  Start({.frames = 20, .frame_interval = std::chrono::milliseconds(10), .peaks_per_frame = 10});
  std::string text;
  std::atomic<bool> subscribed{false};
  std::thread reader([&] {
    Client().Get("/api/v1/events", [&](const char* data, size_t length) {
      subscribed = true;
      text.append(data, length);
      return text.find("\"state\":\"done\"") == std::string::npos;
    });
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (!(subscribed && control_->listeners() == 1) &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(control_->listeners(), 1);
  const std::string id = StartScan();
  reader.join();
  // First the state at subscription (idle), then sweeping, progress steps, done.
  std::vector<protocol::ScanEventMessage> events;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("data: ", 0) == 0) events.push_back(json::parse(line.substr(6)));
  }
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events.front().scan.state, "idle");
  EXPECT_EQ(events.back().type, "state");
  EXPECT_EQ(events.back().scan.state, "done");
  EXPECT_EQ(events.back().scan.scan_id, id);
  double last_progress = 0;
  int progress_events = 0;
  for (const auto& e : events) {
    if (e.type != "progress") continue;
    ++progress_events;
    EXPECT_GE(e.scan.progress, last_progress);
    last_progress = e.scan.progress;
  }
  EXPECT_EQ(progress_events, 20);
  EXPECT_DOUBLE_EQ(last_progress, 1.0);
  // The disconnected client's listener is gone.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (control_->listeners() > 0 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(control_->listeners(), 0);
}

TEST_F(ApiServerTest, StreamsAreLimitedAndPlainRequestsStillServed) {
  std::atomic<bool> stop{false};
  std::vector<std::thread> readers;
  for (int i = 0; i < 4; ++i) {
    readers.emplace_back(
        [&] { Client().Get("/api/v1/events", [&](const char*, size_t) { return !stop.load(); }); });
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (control_->listeners() < 4 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(control_->listeners(), 4);
  ExpectJsonError(Client().Get("/api/v1/events"), 503, "too many");
  auto status = Client().Get("/api/v1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  stop = true;
  server_->Stop();  // ends the streams without waiting for their clients
  for (auto& t : readers) t.join();
}

TEST_F(ApiServerTest, EveryMutatingEndpointNeedsTheToken) {
  const std::string id = CompletedScan();
  struct Call {
    std::string method, path, body;
  };
  const std::vector<Call> calls = {
      {"POST", "/api/v1/scans", ""},
      {"DELETE", "/api/v1/scans/" + id, ""},
      {"PUT", "/api/v1/calibration", R"({"schema":"mirrorscan.calibration"})"},
      {"POST", "/api/v1/captures", R"({"camera":"upper"})"},
  };
  for (const Call& call : calls) {
    SCOPED_TRACE(call.method + " " + call.path);
    for (const auto& [headers, status] : std::vector<std::pair<httplib::Headers, int>>{
             {{}, 401},
             {{{"Authorization", "Basic dXNlcjpwYXNz"}}, 401},
             {{{"Authorization", "Bearer"}}, 401},
             {Auth("virtual-dev-token-not-a-secreT"), 403},
             {Auth(std::string(kToken) + "x"), 403},
             {Auth(""), 401}}) {
      httplib::Client client = Client();
      httplib::Result res =
          call.method == "POST"
              ? client.Post(call.path.c_str(), headers, call.body, "application/json")
          : call.method == "PUT"
              ? client.Put(call.path.c_str(), headers, call.body, "application/json")
              : client.Delete(call.path.c_str(), headers);
      ExpectJsonError(res, status, status == 401 ? "missing bearer token" : "wrong bearer token");
      if (status == 401) {
        EXPECT_EQ(res->get_header_value("WWW-Authenticate"), "Bearer realm=\"mirrorscan\"");
      }
    }
  }
  // Nothing happened: one scan, still there; no calibration.
  EXPECT_EQ(store_->List().size(), 1u);
  EXPECT_FALSE(calibration_->Get().has_value());
}

TEST_F(ApiServerTest, ReadsNeedTheTokenWhenConfigured) {
  Start({}, /*auth_reads=*/true);
  const std::string id = CompletedScan();
  for (const std::string& path : std::vector<std::string>{
           "/api/v1/scans", "/api/v1/scans/" + id, "/api/v1/scans/" + id + "/archive",
           "/api/v1/scans/" + id + "/archive?follow=1", "/api/v1/events", "/api/v1/calibration",
           "/api/v1/nothing-here"}) {
    SCOPED_TRACE(path);
    ExpectJsonError(Client().Get(path), 401, "missing bearer token");
  }
  ExpectJsonError(Client().Get("/api/v1/scans", Auth("wrong-token-wrong-token")), 403, "wrong");
  // The status stays open (no personal data in it) so a device can be found and checked.
  auto status = Client().Get("/api/v1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  auto res = Client().Get("/api/v1/scans/" + id + "/archive", Auth());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->body, ReadFile(store_->Path(id)));
}

TEST_F(ApiServerTest, EveryShippedBoardNeedsTheTokenForReads) {
  for (const char* board : {"virtual", "rpi4", "rpi5"}) {
    SCOPED_TRACE(board);
    EXPECT_TRUE(
        board::BoardConfig::Load(fs::path(MIRRORSCAN_SOURCE_DIR) / "boards" / board / "board.json")
            .service.auth_reads);
  }
}

TEST_F(ApiServerTest, TheBearerSchemeIsCaseInsensitive) {
  for (const std::string scheme : {"bearer ", "BEARER ", "Bearer   "}) {
    SCOPED_TRACE(scheme);
    auto res = Client().Post("/api/v1/scans", {{"Authorization", scheme + kToken}}, "",
                             "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 201) << res->body;
    control_->Join();
  }
}

TEST_F(ApiServerTest, HostileIdsAreRefusedAndTouchNothing) {
  const std::string id = CompletedScan();
  const std::string before = ReadFile(store_->Path(id));
  const fs::path outside = dir_ / "outside.json";
  std::ofstream(outside) << "{}";
  for (const std::string& bad : std::vector<std::string>{
           "..", "%2e%2e", "..%2foutside.json", "%2e%2e%2foutside.json", "." + id, id + "%00",
           id.substr(0, 20), id + "0", "20261124T035501Z-000%2f", "*", std::string(5000, 'a')}) {
    SCOPED_TRACE(bad);
    for (const std::string suffix : {"", "/archive"}) {
      auto get = Client().Get(("/api/v1/scans/" + bad + suffix).c_str());
      ASSERT_TRUE(get);
      EXPECT_GE(get->status, 400);
      EXPECT_LT(get->status, 500);
      EXPECT_TRUE(json::parse(get->body, nullptr, false).is_object()) << get->body;
    }
    auto del = Client().Delete(("/api/v1/scans/" + bad).c_str(), Auth());
    ASSERT_TRUE(del);
    EXPECT_GE(del->status, 400);
    EXPECT_LT(del->status, 500);
  }
  ExpectJsonError(Client().Get("/api/v1/scans/%2e%2e"), 400, "not a scan id");
  ExpectJsonError(Client().Get("/api/v1/scans/..%2f..%2fetc"), 404, "no such endpoint");
  EXPECT_TRUE(fs::exists(outside));
  EXPECT_EQ(ReadFile(store_->Path(id)), before);
  ExpectJsonError(Client().Get("/api/v1/scans/20991231T235959Z-9999"), 404,
                  "20991231T235959Z-9999");
}

TEST_F(ApiServerTest, OversizedBodiesAreRefused) {
  const std::string huge(5u << 20, ' ');
  ExpectJsonError(Client().Put("/api/v1/calibration", Auth(), huge, "application/json"), 413,
                  "too large");
  auto res = Client().Get("/api/v1/status");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_FALSE(calibration_->Get().has_value());
}

TEST_F(ApiServerTest, CalibrationIsValidatedThenStored) {
  ExpectJsonError(Client().Get("/api/v1/calibration"), 404, "no calibration");
  ExpectJsonError(Client().Put("/api/v1/calibration", Auth(), "{oops", "application/json"), 400,
                  "not valid JSON");
  const std::string text =
      ReadFile(fs::path(MIRRORSCAN_SOURCE_DIR) / "firmware/service/testdata/calibration.json");
  json one_mirror = json::parse(text);
  one_mirror["mirrors"].erase(1);
  ExpectJsonError(
      Client().Put("/api/v1/calibration", Auth(), one_mirror.dump(), "application/json"), 400,
      "calibration: mirrors: expected two mirrors");
  EXPECT_FALSE(fs::exists(device_dir_ / "calibration.json"));
  auto put = Client().Put("/api/v1/calibration", Auth(), text, "application/json");
  ASSERT_TRUE(put);
  EXPECT_EQ(put->status, 200) << put->body;
  EXPECT_EQ(json::parse(put->body).at("sha256"), Sha256Of(text));
  EXPECT_EQ(ReadFile(device_dir_ / "calibration.json"), text);

  auto get = Client().Get("/api/v1/calibration");
  ASSERT_TRUE(get);
  EXPECT_EQ(get->body, text);
  EXPECT_EQ(get->get_header_value("X-Mirrorscan-Calibration-SHA256"), Sha256Of(text));
  auto status = Client().Get("/api/v1/status");
  EXPECT_EQ(json::parse(status->body).at("calibration_sha256"), Sha256Of(text));
  EXPECT_EQ(json::parse(status->body).at("calibration_problem"), "");
}

TEST_F(ApiServerTest, CaptureReturnsAGrayImage) {
  auto res = Client().Post("/api/v1/captures", Auth(), R"({"camera":"lower","lasers_on":true})",
                           "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "image/x-portable-graymap");
  EXPECT_EQ(res->get_header_value("X-Mirrorscan-Lasers-On"), "1");
  const std::string header = "P5\n64 48\n255\n";
  ASSERT_EQ(res->body.size(), header.size() + 64 * 48);
  EXPECT_EQ(res->body.substr(0, header.size()), header);
  EXPECT_EQ(static_cast<uint8_t>(res->body[header.size() + 65]), 4 + 1);

  ExpectJsonError(
      Client().Post("/api/v1/captures", Auth(), R"({"camera":"side"})", "application/json"), 400,
      "no camera \"side\"");
  ExpectJsonError(Client().Post("/api/v1/captures", Auth(), R"({"camera":"upper","laser":1})",
                                "application/json"),
                  400, "laser");
  ExpectJsonError(Client().Post("/api/v1/captures", Auth(), "", "application/json"), 400,
                  "request body");
}

TEST_F(ApiServerTest, BusyDeviceRefusesWithConflict) {
  Start({.frames = 40, .frame_interval = std::chrono::milliseconds(20), .peaks_per_frame = 10});
  const std::string id = StartScan();
  ExpectJsonError(Client().Post("/api/v1/scans", Auth(), "", "application/json"), 409, "running");
  ExpectJsonError(Client().Delete(("/api/v1/scans/" + id).c_str(), Auth()), 409, "");
  ExpectJsonError(
      Client().Post("/api/v1/captures", Auth(), R"({"camera":"upper"})", "application/json"), 409,
      "running");
  control_->Join();
  auto del = Client().Delete(("/api/v1/scans/" + id).c_str(), Auth());
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 200);
  ExpectJsonError(Client().Get("/api/v1/scans/" + id), 404, id);
  ExpectJsonError(Client().Post("/api/v1/scans", Auth(), "[1]", "application/json"), 400,
                  "request body");
}

TEST_F(ApiServerTest, UnknownEndpointIsAJson404) {
  ExpectJsonError(Client().Get("/api/v2/status"), 404, "no such endpoint");
  ExpectJsonError(Client().Get("/"), 404, "no such endpoint");
}

using test_support::ConnectLoopback;
using test_support::RawExchange;
using test_support::ReceiveAll;
using test_support::SendAll;

// Requests built from valid pieces, then cut, mutated or replaced by random bytes.
std::string RandomRequest(std::mt19937& rng, const std::string& id) {
  auto pick = [&](const std::vector<std::string>& v) { return v[rng() % v.size()]; };
  const std::string method =
      pick({"GET", "POST", "PUT", "DELETE", "PATCH", "HEAD", "OPTIONS", "G\x01T", "", "GET GET"});
  const std::string path = pick({"/api/v1/status", "/api/v1/scans", "/api/v1/scans/" + id,
                                 "/api/v1/scans/" + id + "/archive", "/api/v1/scans/../../x",
                                 "/api/v1/scans/" + id + "/archive?follow=1&offset=99999999999",
                                 "/api/v1/events?x=%zz", "/api/v1/calibration", "/api/v1/captures",
                                 "%%%", "/" + std::string(rng() % 9000, 'a'), "*"});
  std::string request =
      method + " " + path + " " + pick({"HTTP/1.1", "HTTP/1.0", "HTTP/9", ""}) + "\r\n";
  const int headers = static_cast<int>(rng() % 5);
  for (int i = 0; i < headers; ++i) {
    request +=
        pick({"Host: x", "Authorization: Bearer " + std::string(kToken) + "x",
              "Authorization: Bearer", "Range: bytes=" + std::to_string(rng() % 100000) + "-",
              "Range: bytes=-" + std::to_string(rng()), "Range: bytes=5-1,2-3,junk",
              "Content-Length: " + std::to_string(rng() % 100), "Content-Length: -5",
              "Content-Length: 99999999999999999999", "Transfer-Encoding: chunked",
              "Connection: close", "X: \x7f\xff\r", std::string(rng() % 10000, 'h') + ": v"}) +
        "\r\n";
  }
  request += "\r\n";
  request += pick({"", "{}", "{\"camera\":", "zz\r\n", "5\r\nhello\r\n0\r\n\r\n"});
  switch (rng() % 4) {
    case 0:
      request.resize(rng() % (request.size() + 1));
      break;  // cut anywhere
    case 1:
      for (int i = 0; i < 4 && !request.empty(); ++i) {
        request[rng() % request.size()] = static_cast<char>(rng());
      }
      break;
    case 2: {
      std::string noise(rng() % 2048, '\0');
      for (char& c : noise) c = static_cast<char>(rng());
      request = noise;
      break;
    }
    default:
      break;
  }
  return request;
}

TEST_F(ApiServerTest, SurvivesThousandsOfMalformedAndConcurrentRequests) {
  const std::string id = CompletedScan();
  const std::string archive_before = ReadFile(store_->Path(id));
  const std::string meta_before = ReadFile(device_dir_ / "scans" / (id + ".json"));
  constexpr int kThreads = 4;
  constexpr int kRequestsPerThread = 750;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(40);
  std::atomic<int> sent{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::mt19937 rng(1234 + t);
      for (int i = 0; i < kRequestsPerThread && std::chrono::steady_clock::now() < deadline; ++i) {
        RawExchange(port_, RandomRequest(rng, id));
        ++sent;
      }
    });
  }
  // Well-formed requests keep being answered meanwhile.
  int good = 0;
  while (sent < kThreads * kRequestsPerThread / 2 && std::chrono::steady_clock::now() < deadline) {
    auto res = Client().Get("/api/v1/scans/" + id);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200);
    ++good;
  }
  for (auto& t : threads) t.join();
  std::printf("sent %d random requests; %d good requests answered meanwhile\n", sent.load(), good);
  EXPECT_GE(sent.load(), 2000);
  auto status = Client().Get("/api/v1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  auto archive = Client().Get("/api/v1/scans/" + id + "/archive");
  ASSERT_TRUE(archive);
  EXPECT_EQ(archive->body, archive_before);
  EXPECT_EQ(ReadFile(store_->Path(id)), archive_before);
  EXPECT_EQ(ReadFile(device_dir_ / "scans" / (id + ".json")), meta_before);
  EXPECT_EQ(store_->List().size(), 1u);
}

TEST_F(ApiServerTest, BodiesWithoutATokenAreNeverRead) {
  // 1 GB announced, chunked or with a length: the refusal comes before any body byte is
  // sent, and the connection is closed instead of reading on.
  for (const std::string& framing :
       {std::string("Transfer-Encoding: chunked"), std::string("Content-Length: 1000000000")}) {
    SCOPED_TRACE(framing);
    const int fd = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(SendAll(fd, "PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\n" + framing +
                                "\r\nContent-Type: application/json\r\n\r\n"));
    const std::string reply = ReceiveAll(fd);  // the server closes: the read ends
    ::close(fd);
    EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply;
    EXPECT_NE(reply.find("Connection: close"), std::string::npos) << reply;
  }
  // Without a token and without a body the answer is 401 too, not "malformed".
  ExpectJsonError(Client().Post("/api/v1/scans", "", ""), 401, "missing bearer token");
  // Expect: 100-continue is answered with the refusal, not with "100 Continue".
  const int fd = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(SendAll(fd,
                      "PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\nContent-Length: "
                      "100\r\nExpect: 100-continue\r\n\r\n"));
  const std::string reply = ReceiveAll(fd);
  ::close(fd);
  EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply;
  EXPECT_FALSE(calibration_->Get().has_value());
}

TEST_F(ApiServerTest, BodiesOverTheLimitAreRefusedBeforeOrWhileRead) {
  // A declared length over the limit: 413 at once, with the token.
  const int fd = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(SendAll(fd, "PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                              std::string(kToken) + "\r\nContent-Length: 1000000000\r\n\r\n"));
  std::string reply = ReceiveAll(fd);
  ::close(fd);
  EXPECT_EQ(reply.rfind("HTTP/1.1 413", 0), 0u) << reply;
  // Chunked, with the token: cut once the body passes 4 MiB, not read to its end.
  const int chunked = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
  ASSERT_GE(chunked, 0);
  ASSERT_TRUE(
      SendAll(chunked, "PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                           std::string(kToken) + "\r\nTransfer-Encoding: chunked\r\n\r\n"));
  const std::string chunk = "10000\r\n" + std::string(0x10000, ' ') + "\r\n";
  size_t sent = 0;
  while (sent < (64u << 20) && SendAll(chunked, chunk)) sent += 0x10000;
  reply = ReceiveAll(chunked);
  ::close(chunked);
  // 4 MiB read, then at most 16 MiB discarded while the refusal is read, plus what the
  // loopback socket buffers hold: never the whole 64 MiB.
  EXPECT_LT(sent, 32u << 20) << "the server kept reading";
  EXPECT_GE(sent, 4u << 20);
  EXPECT_EQ(reply.rfind("HTTP/1.1 413", 0), 0u) << reply.substr(0, 200);
  // No Content-Length and no Transfer-Encoding (`curl -X POST`): no body, answered at once.
  const int bare = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
  ASSERT_GE(bare, 0);
  const auto bare_start = std::chrono::steady_clock::now();
  ASSERT_TRUE(SendAll(bare, "POST /api/v1/scans HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                                std::string(kToken) + "\r\nConnection: close\r\n\r\n"));
  reply = ReceiveAll(bare);
  ::close(bare);
  EXPECT_EQ(reply.rfind("HTTP/1.1 201", 0), 0u) << reply;
  EXPECT_LT(std::chrono::steady_clock::now() - bare_start, std::chrono::seconds(2));
  control_->Join();
  // A small chunked body with the token is read whole.
  const int good = ConnectLoopback(port_, "127.0.0.1", std::chrono::milliseconds(3000));
  ASSERT_GE(good, 0);
  ASSERT_TRUE(SendAll(good, "POST /api/v1/scans HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                                std::string(kToken) +
                                "\r\nConnection: close\r\nTransfer-Encoding: chunked\r\n\r\n"
                                "2\r\n{}\r\n0\r\n\r\n"));
  reply = ReceiveAll(good);
  ::close(good);
  EXPECT_EQ(reply.rfind("HTTP/1.1 201", 0), 0u) << reply;
  control_->Join();
}

TEST_F(ApiServerTest, WrongTokensAreRateLimitedPerAddress) {
  int forbidden = 0;
  int limited = 0;
  for (int i = 0; i < 30; ++i) {
    auto res = Client().Delete("/api/v1/scans/20990101T000000Z-0001",
                               Auth("wrong-token-number-" + std::to_string(i)));
    ASSERT_TRUE(res);
    (res->status == 403 ? forbidden : limited) += 1;
    if (res->status == 429) {
      EXPECT_FALSE(res->get_header_value("Retry-After").empty());
      ExpectJsonError(res, 429, "too many wrong tokens");
    }
  }
  EXPECT_EQ(forbidden, 10);  // the burst
  EXPECT_EQ(limited, 20);
  // Even the right token waits: the limit is on the address, not on a guess.
  auto res = Client().Post("/api/v1/scans", Auth(), "", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 429);
}

TEST_F(ApiServerTest, AbortStopsTheRunningScan) {
  ExpectJsonError(Client().Post("/api/v1/scans/current/abort", Auth(), "", "application/json"), 409,
                  "no scan is running");
  ExpectJsonError(Client().Post("/api/v1/scans/current/abort", "", "application/json"), 401,
                  "missing bearer token");
  Start({.frames = 2000, .frame_interval = std::chrono::milliseconds(5)});
  const std::string id = StartScan();
  auto res = Client().Post("/api/v1/scans/current/abort", Auth(), R"({"reason":"operator"})",
                           "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(json::parse(res->body).value("aborted", ""), id);
  control_->Join();
  EXPECT_EQ(store_->Get(id).state, store::ScanState::kAborted);
}

TEST_F(ApiServerTest, AMalformedRangeStillNamesTheArchiveSize) {
  const std::string id = CompletedScan();
  const size_t size = fs::file_size(store_->Path(id));
  // httplib refuses these before routing; the handler refuses the rest.
  for (const std::string range :
       {"bytes=abc", "bytes=1-2,", "bytes", "bytes=--1", "bytes=99999999999-", "items=0-1"}) {
    SCOPED_TRACE(range);
    auto res = Client().Get("/api/v1/scans/" + id + "/archive", {{"Range", range}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 416);
    EXPECT_EQ(res->get_header_value("Content-Range"), "bytes */" + std::to_string(size));
  }
}

TEST_F(ApiServerTest, ConnectionsArePerAddressBoundedAndDeadlined) {
  limits_.per_client = 4;
  limits_.total = 12;
  limits_.header_timeout = std::chrono::milliseconds(1000);
  Start({});
  // One address holding idle sockets: the fifth is refused at once with a 503.
  std::vector<int> idle;
  for (int i = 0; i < 4; ++i)
    idle.push_back(ConnectLoopback(port_, "127.0.0.2", std::chrono::milliseconds(3000)));
  for (const int fd : idle) ASSERT_GE(fd, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // all four admitted
  const int fifth = ConnectLoopback(port_, "127.0.0.2", std::chrono::milliseconds(3000));
  ASSERT_GE(fifth, 0);
  const std::string refused = ReceiveAll(fifth);
  ::close(fifth);
  EXPECT_EQ(refused.rfind("HTTP/1.1 503", 0), 0u) << refused;
  // Other addresses fill the total; a new client still gets served (the longest idle
  // connection makes room), and quickly.
  std::vector<int> others;
  for (const char* source : {"127.0.0.3", "127.0.0.4"}) {
    for (int i = 0; i < 4; ++i)
      others.push_back(ConnectLoopback(port_, source, std::chrono::milliseconds(3000)));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto start = std::chrono::steady_clock::now();
  auto status = Client().Get("/api/v1/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(900));
  // A trickling client (a header byte every 200 ms) is cut at the header deadline.
  const int trickle = ConnectLoopback(port_, "127.0.0.5", std::chrono::milliseconds(3000));
  ASSERT_GE(trickle, 0);
  const auto trickle_start = std::chrono::steady_clock::now();
  const std::string request = "GET /api/v1/status HTTP/1.1\r\nX-Slow: " + std::string(100, 'a');
  size_t i = 0;
  for (; i < request.size() && SendAll(trickle, request.substr(i, 1)); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  const double held =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - trickle_start).count();
  ::close(trickle);
  EXPECT_LT(i, request.size());
  EXPECT_LT(held, 3.0);  // 1 s deadline, then the send fails within a few more tries
  for (const int fd : idle) ::close(fd);
  for (const int fd : others) ::close(fd);
}

}  // namespace
}  // namespace mirrorscan::service

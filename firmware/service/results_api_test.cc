// What the device's web page uses: PUT/GET /api/v1/scans/{id}/results/{name} (the host's
// processed results stored with a scan), the live preview and the static page, against an
// in-process ApiServer on loopback with the real ScanStore.

#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <httplib.h>

#include "common/protocol/protocol.h"
#include "firmware/service/api_server.h"
#include "tests/support/in_process_device.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using test_support::ExpectJsonError;
using test_support::ReadFile;
const std::string kPng = std::string("\x89PNG\r\n\x1a\n", 8) + std::string(3000, '\x01');
const std::string kPly =
    "ply\nformat binary_little_endian 1.0\nend_header\n" + std::string(5000, 'x');

class ResultsApiTest : public ::testing::Test {
 protected:
  void SetUp() override { Start(false); }

  // A new device in a new folder (dir_/device<n>), serving a small page.
  void Start(bool open_reads) {
    device_.reset();
    device_dir_ = dir_ / ("device" + std::to_string(starts_++));
    fs::create_directories(device_dir_ / "web");
    std::ofstream(device_dir_ / "web" / "index.html") << "<!doctype html><title>mirrorscan</title>";
    std::ofstream(device_dir_ / "web" / "app.js") << "console.log('page');";
    test_support::InProcessDeviceOptions options;
    options.auth_reads = !open_reads;
    options.server.web_dir = device_dir_ / "web";
    options.server.preview_interval = std::chrono::milliseconds(60000);
    device_ = std::make_unique<test_support::InProcessDevice>(device_dir_, options);
  }

  httplib::Client Client() const { return device_->Client(); }
  static httplib::Headers Auth(const std::string& token = test_support::kVirtualToken) {
    return test_support::BearerAuth(token);
  }
  std::string CompletedScan() {
    auto res = Client().Post("/api/v1/scans", Auth(), "", "application/json");
    EXPECT_TRUE(res && res->status == 201);
    device_->control->Join();
    return json::parse(res->body).at("id").get<std::string>();
  }
  httplib::Result Put(const std::string& id, const std::string& name, const std::string& body,
                      const httplib::Headers& headers = Auth()) {
    return Client().Put("/api/v1/scans/" + id + "/results/" + name, headers, body,
                        "application/octet-stream");
  }

  const test_support::TempDir dir_{"results_api_test"};
  int starts_ = 0;
  fs::path device_dir_;
  std::unique_ptr<test_support::InProcessDevice> device_;
};

TEST_F(ResultsApiTest, PutResultsAreListedAndServedByteForByte) {
  const std::string id = CompletedScan();
  const std::string summary = R"({"ok": true, "scan_id": ")" + id + R"("})";
  for (const auto& [name, body] : {std::pair<std::string, std::string>{"mesh.ply", kPly},
                                   {"preview-front.png", kPng},
                                   {"summary.json", summary}}) {
    auto res = Put(id, name, body);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << name << ": " << res->body;
    EXPECT_EQ(json::parse(res->body).value("bytes", 0u), body.size());
  }
  auto list = Client().Get("/api/v1/scans/" + id + "/results", Auth());
  ASSERT_TRUE(list && list->status == 200);
  const json results = json::parse(list->body).at("results");
  ASSERT_EQ(results.size(), 3u);
  EXPECT_EQ(results[0].at("name"), "mesh.ply");
  EXPECT_EQ(results[0].at("bytes"), kPly.size());
  EXPECT_EQ(results[1].at("name"), "preview-front.png");
  EXPECT_EQ(results[2].at("name"), "summary.json");
  // The scan itself names its results (the page's list shows which scans are processed).
  auto scan = Client().Get("/api/v1/scans/" + id, Auth());
  ASSERT_TRUE(scan);
  EXPECT_EQ(json::parse(scan->body).at("results"),
            json({"mesh.ply", "preview-front.png", "summary.json"}));

  auto png = Client().Get("/api/v1/scans/" + id + "/results/preview-front.png", Auth());
  ASSERT_TRUE(png && png->status == 200);
  EXPECT_EQ(png->body, kPng);
  EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(png->get_header_value("Cache-Control"), "no-store");
  auto mesh = Client().Get("/api/v1/scans/" + id + "/results/mesh.ply", Auth());
  ASSERT_TRUE(mesh && mesh->status == 200);
  EXPECT_EQ(mesh->body, kPly);
  // Stored beside the scan in the data directory.
  EXPECT_EQ(ReadFile(device_dir_ / "scans" / (id + ".results") / "summary.json"), summary);
  // A second upload replaces the first whole.
  ASSERT_EQ(Put(id, "summary.json", R"({"ok": false})")->status, 200);
  EXPECT_EQ(Client().Get("/api/v1/scans/" + id + "/results/summary.json", Auth())->body,
            R"({"ok": false})");
}

TEST_F(ResultsApiTest, PutNeedsTheTokenAndReadsNeedItOnThisBoard) {
  const std::string id = CompletedScan();
  ExpectJsonError(Put(id, "mesh.ply", kPly, {}), 401, "missing bearer token");
  ExpectJsonError(Put(id, "mesh.ply", kPly, Auth("wrong-token-wrong-token-wrong-token")), 403,
                  "wrong bearer token");
  ASSERT_EQ(Put(id, "mesh.ply", kPly)->status, 200);
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/results"), 401, "missing bearer token");
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/results/mesh.ply"), 401,
                  "missing bearer token");
}

TEST_F(ResultsApiTest, OnlyTheListedNamesAndMatchingContentAreStored) {
  const std::string id = CompletedScan();
  for (const char* name :
       {"points.ply", "mesh.obj", "notes.txt", "..%2f..%2fetc", "summary.json.tmp-1", "%2e%2e"}) {
    auto res = Put(id, name, kPly);
    ASSERT_TRUE(res) << name;
    EXPECT_TRUE(res->status == 404 || res->status == 400) << name << ": " << res->status;
  }
  ExpectJsonError(Put(id, "preview-back.png", "GIF89a not a png"), 400, "not a PNG");
  ExpectJsonError(Put(id, "mesh.ply", "solid stl\n"), 400, "not a PLY");
  ExpectJsonError(Put(id, "measurements.json", "[1, 2]"), 400, "not a JSON object");
  ExpectJsonError(Put(id, "measurements.json", "{oops"), 400, "not a JSON object");
  ExpectJsonError(Put(id, "summary.json", ""), 400, "expected the result's bytes");
  ExpectJsonError(Put("20000101T000000Z-0001", "mesh.ply", kPly), 404, "no scan");
  ExpectJsonError(Put("not-an-id", "mesh.ply", kPly), 400, "not a scan id");
  // Nothing of the refused uploads was kept.
  auto list = Client().Get("/api/v1/scans/" + id + "/results", Auth());
  ASSERT_TRUE(list);
  EXPECT_TRUE(json::parse(list->body).at("results").empty()) << list->body;
  size_t files = 0;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(device_dir_ / "scans" / (id + ".results"), ec)) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 0u);
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/results/mesh.ply", Auth()), 404,
                  "no result mesh.ply");
}

TEST_F(ResultsApiTest, EachNameHasItsSizeLimit) {
  const std::string id = CompletedScan();
  const protocol::ResultKind* json_kind = protocol::FindResultKind("summary.json");
  ASSERT_NE(json_kind, nullptr);
  // Declared too large: 413 before the body is read.
  ExpectJsonError(
      Put(id, "summary.json", "{\"a\":\"" + std::string(json_kind->max_bytes, 'a') + "\"}"), 413,
      "too large");
  // A mesh over the general 4 MiB body limit but within its own is stored.
  const std::string big_mesh = kPly + std::string(5u << 20, 'v');
  auto res = Put(id, "mesh.ply", big_mesh);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(fs::file_size(device_dir_ / "scans" / (id + ".results") / "mesh.ply"), big_mesh.size());
  // Chunked past the limit: cut as it passes it.
  httplib::Client client = Client();
  const std::string piece(64 << 10, ' ');
  size_t sent = 0;
  auto chunked = client.Put(
      "/api/v1/scans/" + id + "/results/measurements.json", Auth(),
      [&](size_t, httplib::DataSink& sink) {
        if (sent == 0) sink.write("{\"a\":\"", 6);
        if (sent > (64u << 20)) {
          sink.done();
          return true;
        }
        sent += piece.size();
        return sink.write(piece.data(), piece.size());
      },
      "application/json");
  if (chunked) {
    EXPECT_EQ(chunked->status, 413) << chunked->body;
  }
  // 1 MiB read, then at most 16 MiB discarded while the refusal is read, plus what the
  // socket buffers hold: never all 64 MiB.
  EXPECT_LT(sent, 40u << 20);
  EXPECT_FALSE(fs::exists(device_dir_ / "scans" / (id + ".results") / "measurements.json"));
}

TEST_F(ResultsApiTest, ResultsAreDeletedWithTheScan) {
  const std::string id = CompletedScan();
  ASSERT_EQ(Put(id, "mesh.ply", kPly)->status, 200);
  auto res = Client().Delete("/api/v1/scans/" + id, Auth());
  ASSERT_TRUE(res && res->status == 200);
  EXPECT_FALSE(fs::exists(device_dir_ / "scans" / (id + ".results")));
  ExpectJsonError(Client().Get("/api/v1/scans/" + id + "/results", Auth()), 404, "no scan");
}

TEST_F(ResultsApiTest, AScanBeingWrittenTakesNoResults) {
  device_->server.reset();  // before the control it holds; both replaced by a slow one
  TestScanControl::Options slow;
  slow.frames = 200;
  slow.frame_interval = std::chrono::milliseconds(10);
  device_->control = std::make_unique<TestScanControl>(*device_->store, slow);
  device_->Serve({});
  auto start = Client().Post("/api/v1/scans", Auth(), "", "application/json");
  ASSERT_TRUE(start && start->status == 201);
  const std::string id = json::parse(start->body).at("id").get<std::string>();
  ExpectJsonError(Put(id, "mesh.ply", kPly), 409, "being written");
  device_->control->Abort("test");
  device_->control->Join();
}

TEST_F(ResultsApiTest, ThePageIsServedWithoutTheTokenAndRunsOnlyItsOwnScripts) {
  auto page = Client().Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<title>mirrorscan</title>"), std::string::npos);
  EXPECT_NE(page->get_header_value("Content-Security-Policy").find("script-src 'self'"),
            std::string::npos);
  auto script = Client().Get("/app.js");
  ASSERT_TRUE(script && script->status == 200);
  EXPECT_NE(script->get_header_value("Content-Type").find("javascript"), std::string::npos);
  // Outside the folder: nothing.
  for (const char* path : {"/../results_api_test", "/%2e%2e/scans", "/nothing.js"}) {
    auto res = Client().Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 404) << path;
  }
  // The API behind it still needs the token.
  ExpectJsonError(Client().Get("/api/v1/scans"), 401, "missing bearer token");
}

TEST_F(ResultsApiTest, ThePreviewIsAPngWithThePeakCountAndSharedBetweenViewers) {
  auto res = Client().Get("/api/v1/preview?camera=upper", Auth());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(res->body.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_FALSE(res->get_header_value("X-Mirrorscan-Peaks").empty());
  EXPECT_EQ(res->get_header_value("Cache-Control"), "no-store");
  // Within the interval a second viewer gets the same frame, not a new capture.
  auto again = Client().Get("/api/v1/preview?camera=upper", Auth());
  ASSERT_TRUE(again);
  EXPECT_EQ(again->body, res->body);
  ExpectJsonError(Client().Get("/api/v1/preview?camera=side", Auth()), 400, "no camera");
  ExpectJsonError(Client().Get("/api/v1/preview?camera=upper&lasers=2", Auth()), 400, "lasers");
  ExpectJsonError(Client().Get("/api/v1/preview?camera=upper"), 401, "missing bearer token");
}

TEST_F(ResultsApiTest, APreviewWithLasersNeedsTheTokenEvenWithOpenReads) {
  Start(/*open_reads=*/true);
  auto dark = Client().Get("/api/v1/preview?camera=lower");
  ASSERT_TRUE(dark);
  EXPECT_EQ(dark->status, 200);
  ExpectJsonError(Client().Get("/api/v1/preview?camera=lower&lasers=1"), 401,
                  "missing bearer token");
  auto lit = Client().Get("/api/v1/preview?camera=lower&lasers=1", Auth());
  ASSERT_TRUE(lit);
  EXPECT_EQ(lit->status, 200);
}

TEST_F(ResultsApiTest, StatusNamesTheCameras) {
  auto res = Client().Get("/api/v1/status");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(json::parse(res->body).at("cameras"), json({"upper", "lower", "up"}));
}

}  // namespace
}  // namespace mirrorscan::service

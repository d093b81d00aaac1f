#include "tests/support/in_process_device.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/protocol/protocol.h"

namespace mirrorscan::test_support {

InProcessDevice::InProcessDevice(const std::filesystem::path& dir,
                                 const InProcessDeviceOptions& options) {
  std::filesystem::create_directories(dir);
  board = board::BoardConfig::Load(std::filesystem::path(MIRRORSCAN_SOURCE_DIR) /
                                   "boards/virtual/board.json");
  board.service.auth_reads = options.auth_reads;
  store = store::ScanStore::Open(dir / "scans");
  control = std::make_unique<service::TestScanControl>(*store, options.scan);
  calibration = std::make_unique<service::CalibrationStore>(dir / "calibration.json");
  Serve(options.server);
}

InProcessDevice::~InProcessDevice() { server.reset(); }

void InProcessDevice::Serve(const service::ApiServerOptions& options) {
  server.reset();
  server = std::make_unique<service::ApiServer>(*store, *control, board, *calibration,
                                                kVirtualToken, options);
  port = server->Start("127.0.0.1:0");
}

httplib::Client InProcessDevice::Client() const {
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(10, 0);
  return client;
}

httplib::Headers BearerAuth(const std::string& token) {
  return {{"Authorization", "Bearer " + token}};
}

void ExpectJsonError(const httplib::Result& res, int status, const std::string& words) {
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, status) << res->body;
  EXPECT_EQ(res->get_header_value("X-Mirrorscan-Api-Version"), "1");
  const nlohmann::json body = nlohmann::json::parse(res->body, nullptr, false);
  ASSERT_TRUE(body.is_object()) << res->body;
  EXPECT_EQ(body.value("error", ""), protocol::ErrorCode(status)) << res->body;
  EXPECT_NE(body.value("message", "").find(words), std::string::npos) << res->body;
}

}  // namespace mirrorscan::test_support

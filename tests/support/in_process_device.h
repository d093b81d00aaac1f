#pragma once
// The device API in process on loopback, for the tests of the API and of its clients: the
// real ApiServer, ScanStore (<dir>/scans) and CalibrationStore (<dir>/calibration.json),
// TestScanControl in place of the sequencer, the virtual board's board.json.

#include <filesystem>
#include <memory>
#include <string>

#include <httplib.h>

#include "firmware/board/board_config.h"
#include "firmware/service/api_server.h"
#include "firmware/service/calibration_store.h"
#include "firmware/service/test_scan_control.h"
#include "firmware/store/scan_store.h"

namespace mirrorscan::test_support {

// boards/virtual/board.json's service.token.
inline constexpr char kVirtualToken[] = "virtual-dev-token-not-a-secret";

struct InProcessDeviceOptions {
  service::TestScanControl::Options scan;
  service::ApiServerOptions server;
  bool auth_reads = true;  // replaces the board's service.auth_reads
};

struct InProcessDevice {
  // Opens the stores under `dir` (created if missing) and serves on 127.0.0.1:<free port>.
  InProcessDevice(const std::filesystem::path& dir, const InProcessDeviceOptions& options);
  ~InProcessDevice();  // the server first: it holds the others
  InProcessDevice(const InProcessDevice&) = delete;
  InProcessDevice& operator=(const InProcessDevice&) = delete;

  // (Re)starts the server on the current members (a test may swap `control` between), on a
  // new port.
  void Serve(const service::ApiServerOptions& options);
  // An httplib client to it, reads time out after 10 s.
  httplib::Client Client() const;

  board::BoardConfig board;
  std::unique_ptr<store::ScanStore> store;
  std::unique_ptr<service::TestScanControl> control;
  std::unique_ptr<service::CalibrationStore> calibration;
  std::unique_ptr<service::ApiServer> server;
  int port = 0;
};

httplib::Headers BearerAuth(const std::string& token = kVirtualToken);

// `res` is the API's JSON error: `status`, the API version header, "error" the status's
// code and a "message" that holds `words`.
void ExpectJsonError(const httplib::Result& res, int status, const std::string& words);

}  // namespace mirrorscan::test_support

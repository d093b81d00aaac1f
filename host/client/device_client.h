#pragma once

// The host's side of the device API (docs/device-api.md): one DeviceClient per device.
// Downloads resume after dropped connections and are verified against the device's
// SHA-256; a followed archive streams while the scan runs.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/protocol/protocol.h"

namespace mirrorscan::client {

// A refusal from the device (status 4xx/5xx, with its error code and message) or a
// connection failure (status 0). what() is one line for the user.
class DeviceError : public std::runtime_error {
 public:
  DeviceError(int status, std::string code, const std::string& message)
      : std::runtime_error(message), status_(status), code_(std::move(code)) {}
  int status() const { return status_; }
  const std::string& code() const { return code_; }

 private:
  int status_;
  std::string code_;
};

struct DeviceClientOptions {
  std::chrono::seconds connect_timeout{5};
  std::chrono::seconds read_timeout{30};
  int max_retries = 5;  // reconnects per download after a dropped connection
  std::chrono::milliseconds retry_delay{300};
};

// Progress of a download: bytes on disk so far and the total (0 while unknown: a followed
// scan still being written). `frames` counts frame records seen (follow only).
struct TransferProgress {
  uint64_t bytes = 0;
  uint64_t total = 0;
  uint64_t frames = 0;
  int reconnects = 0;
};
using ProgressCallback = std::function<void(const TransferProgress&)>;

struct FetchResult {
  std::filesystem::path path;
  uint64_t bytes = 0;
  std::string sha256;  // verified against the device's
  int reconnects = 0;
};

class DeviceClient {
 public:
  // `host_port` is "host:port" (or "host", port 8080); `token` may be empty for reads.
  DeviceClient(const std::string& host_port, std::string token, DeviceClientOptions options = {});
  ~DeviceClient();

  protocol::DeviceStatus Status();
  std::vector<protocol::ScanSummary> List();
  protocol::ScanSummary Get(const std::string& id);
  std::string StartScan();  // the new scan's id
  // Aborts the running scan (POST /scans/current/abort); returns its id. DeviceError 409
  // when no scan runs.
  std::string AbortScan(const std::string& reason = "");
  void Delete(const std::string& id);

  // Downloads a finished scan to `out` through `out`.partial: resumes from the partial
  // file (also one left by an earlier run) with Range after a dropped connection,
  // verifies the SHA-256 the device sends, then renames into place. A checksum mismatch
  // removes the partial file and throws.
  FetchResult Fetch(const std::string& id, const std::filesystem::path& out,
                    const ProgressCallback& progress = nullptr);
  // Streams a scan's archive live (?follow=1) into `out`.partial while it is written,
  // resuming at the partial file's size after a dropped connection, until the device ends
  // the stream after the footer; then verifies the SHA-256 and renames into place.
  FetchResult Follow(const std::string& id, const std::filesystem::path& out,
                     const ProgressCallback& progress = nullptr);

  std::string GetCalibration();                         // the stored calibration.json text
  std::string PutCalibration(const std::string& text);  // returns the stored SHA-256
  // One raw frame as binary PGM.
  std::string Capture(const std::string& camera, bool lasers_on);
  // Stores `file` as the scan's result `name` (protocol::ResultKinds; needs the token).
  // DeviceError 400 (content), 404 (no such scan or name), 409, 413.
  void PutResult(const std::string& id, const std::string& name, const std::filesystem::path& file);
  std::vector<protocol::ResultInfo> Results(const std::string& id);
  std::string GetResult(const std::string& id, const std::string& name);
  // Calls `on_event` for each server-sent event until it returns false.
  void Events(const std::function<bool(const protocol::ScanEventMessage&)>& on_event);

  const std::string& host_port() const { return host_port_; }

 private:
  struct Http;
  std::string ArchiveSha256(const std::string& id);

  std::string host_port_;
  std::string token_;
  DeviceClientOptions options_;
  std::unique_ptr<Http> http_;
};

}  // namespace mirrorscan::client

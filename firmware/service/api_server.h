#pragma once

// The device HTTP API (docs/device-api.md) on cpp-httplib: status, scans, archive
// download with Range and SHA-256, live archive follow, server-sent events, calibration
// and raw captures. It only uses the ScanControl interface, the scan store and the board
// config, so it is built and tested apart from the sequencer.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "common/protocol/protocol.h"
#include "firmware/board/board_config.h"
#include "firmware/scan/scan_control.h"
#include "firmware/service/calibration_store.h"
#include "firmware/service/connection_guard.h"
#include "firmware/store/scan_store.h"

namespace httplib {
struct Request;
struct Response;
class ContentReader;
}  // namespace httplib

namespace mirrorscan::service {

class GuardedServer;

struct ApiServerOptions {
  std::string firmware_version;
  // Larger bodies get 413 before a byte of them is read, chunked ones as soon as they
  // pass it (a calibration is ~10 kB).
  size_t max_body_bytes = 4u << 20;
  ConnectionLimits connections{};  // per client, in total, deadlines (connection_guard.h)
  // Live streams (archive follow and events) at once; each holds a connection, so this
  // stays below connections.total. More get 503.
  int max_streams = 4;
  std::chrono::milliseconds follow_poll{25};    // how often a follow looks for new bytes
  FailedTokenLimiter::Options failed_tokens{};  // wrong tokens per client before 429
  // Below this much free space the status says the disk is full (a scan needs ~10 MB
  // per 100 mm of sweep).
  uint64_t min_free_bytes = 64u << 20;
  // A comment line on a quiet SSE stream: keeps proxies open and finds vanished clients
  // (their listener is dropped at the first failed write).
  std::chrono::milliseconds keepalive_interval{5000};
  // The web page's static files (index.html, app.js, style.css), served at "/" with no
  // token (they hold no personal data; every API call the page makes sends it). Empty:
  // no page.
  std::filesystem::path web_dir;
  // The live preview captures at most once per this interval and camera; more viewers
  // share that frame.
  std::chrono::milliseconds preview_interval{500};
  int preview_scale = 2;  // the preview's shrink factor
};

class ApiServer {
 public:
  // All references must outlive the server. `token` is the bearer token
  // (ResolveServiceToken); `calibration` holds <data-dir>/calibration.json.
  ApiServer(store::ScanStore& store, scan::ScanControl& control, const board::BoardConfig& board,
            CalibrationStore& calibration, std::string token, ApiServerOptions options = {});
  ~ApiServer();
  ApiServer(const ApiServer&) = delete;
  ApiServer& operator=(const ApiServer&) = delete;

  // Binds "host:port" (port 0 picks a free one) and serves on background threads; returns
  // the bound port. Throws std::runtime_error when the address cannot be bound.
  int Start(const std::string& listen);
  // Ends live streams, stops accepting and joins the threads. Idempotent.
  void Stop();

 private:
  using Request = httplib::Request;
  using Response = httplib::Response;

  void Route();
  // The token check for everything but GET /status (and reads on an open-reads board),
  // run before a body is read. False with the refusal (401/403/429) in `res`.
  bool Authorize(const Request& req, Response& res);
  // Whether `req` needs the token at all.
  bool NeedsToken(const Request& req) const;
  // The body limit against Content-Length, before reading; false with a 413 in `res`.
  bool BodyFits(const Request& req, Response& res) const;
  void HandleStatus(const Request& req, Response& res);
  void HandleListScans(const Request& req, Response& res);
  void HandleStartScan(const Request& req, Response& res);
  void HandleGetScan(const Request& req, Response& res);
  void HandleDeleteScan(const Request& req, Response& res);
  void HandleAbort(const Request& req, Response& res);
  void HandleArchive(const Request& req, Response& res);
  void ServeArchiveFile(const Request& req, Response& res, const std::string& id);
  void FollowArchive(const Request& req, Response& res, const std::string& id);
  void HandleEvents(const Request& req, Response& res);
  void HandleGetCalibration(const Request& req, Response& res);
  void HandlePutCalibration(const Request& req, Response& res);
  void HandleCapture(const Request& req, Response& res);
  void HandlePreview(const Request& req, Response& res);
  void HandleListResults(const Request& req, Response& res);
  void HandleGetResult(const Request& req, Response& res);
  void HandleEmptyResult(const Request& req, Response& res);
  // Streams the body into the store's upload (the per-name limit applied as it arrives).
  void HandlePutResult(const Request& req, Response& res, const httplib::ContentReader& read);
  // The body limit of this request: a result's own (protocol::ResultKind) or max_body_bytes.
  size_t BodyLimit(const Request& req) const;
  protocol::ScanSummary Summary(const store::ScanInfo& info) const;
  // Takes a live-stream slot; false (and a 503 sent) when all are taken.
  bool AcquireStream(Response& res);
  // The SHA-256 of a finished archive, computed once per (id, size, mtime).
  std::string ArchiveSha256(const std::string& id, const std::filesystem::path& path);

  store::ScanStore& store_;
  scan::ScanControl& control_;
  const board::BoardConfig& board_;
  CalibrationStore& calibration_;
  const std::string token_;
  const ApiServerOptions options_;
  std::unique_ptr<GuardedServer> server_;
  FailedTokenLimiter failed_tokens_;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> listen_ended_{false};
  std::atomic<int> streams_{0};
  std::mutex sha_mutex_;
  struct ShaEntry {
    uintmax_t size = 0;
    std::filesystem::file_time_type mtime;
    std::string sha256;
  };
  std::map<std::string, ShaEntry> sha_cache_;
  struct PreviewEntry {
    std::chrono::steady_clock::time_point time;
    std::string png;
    size_t peaks = 0;
  };
  std::mutex preview_mutex_;  // one capture at a time; held while capturing
  std::map<std::string, PreviewEntry> preview_cache_;
};

}  // namespace mirrorscan::service

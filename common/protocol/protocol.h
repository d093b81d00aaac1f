#pragma once

// The device API's shared vocabulary (docs/device-api.md): version, paths, headers, the
// JSON bodies of status, scans, events and errors, and scan id validation. The firmware's
// server and the host's client both use it, so the two cannot drift apart.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace mirrorscan::protocol {

inline constexpr int kApiVersion = 1;
inline constexpr std::string_view kApiPrefix = "/api/v1";
// Every response carries the API version in this header (and JSON bodies in "api_version").
inline constexpr std::string_view kApiVersionHeader = "X-Mirrorscan-Api-Version";
// A finished archive's SHA-256 (lower-case hex), also its ETag.
inline constexpr std::string_view kSha256Header = "X-Mirrorscan-SHA256";
// The stored calibration's SHA-256.
inline constexpr std::string_view kCalibrationSha256Header = "X-Mirrorscan-Calibration-SHA256";
// The environment variable the CLI reads the bearer token from.
inline constexpr std::string_view kTokenEnvironmentVariable = "MIRRORSCAN_TOKEN";
// DNS-SD service type the device announces.
inline constexpr std::string_view kServiceType = "_mirrorscan._tcp";

// "YYYYMMDDTHHMMSSZ-NNNN" (UTC start time, then a counter): exactly 21 ASCII characters,
// digits where digits go. Anything else (including "..", "/", "%2f") is not an id, and no
// file path is ever formed from it.
bool IsValidScanId(std::string_view id);

// The sequencer's view of the running (or last) scan.
struct ScanProgress {
  std::string state = "idle";  // scan::SequencerStateName
  std::string scan_id;
  double progress = 0.0;  // 0..1 along the sweep
  double position_mm = 0.0;
  uint64_t frames = 0;
  uint64_t peaks = 0;
  uint64_t dropped = 0;
  std::string reason;
};

struct DiskUse {
  uint64_t total_bytes = 0;
  uint64_t free_bytes = 0;
  uint64_t scans_bytes = 0;  // archives and metadata in the store
  // Too little room to start a scan, or the store could not write its metadata; `problem`
  // says which and that deleting scans (which needs no free space) makes room.
  bool full = false;
  std::string problem;
};

// GET /api/v1/status
struct DeviceStatus {
  std::string board;
  std::string firmware_version;
  std::string calibration_sha256;  // empty: no calibration stored
  // Why the calibration found at start was set aside (empty: none was).
  std::string calibration_problem;
  std::vector<std::string> cameras;  // the board's camera names (for captures, previews)
  ScanProgress scan;
  DiskUse disk;
};

// One scan in GET /api/v1/scans and GET /api/v1/scans/{id}.
struct ScanSummary {
  std::string id;
  std::string state;  // "writing", "complete", "aborted", "fault", "partial"
  std::string reason;
  std::string created;  // UTC, "2026-11-24T02:55:01Z"
  uint64_t frames = 0;
  uint64_t peaks = 0;
  uint64_t bytes = 0;
  nlohmann::json header = nlohmann::json::object();
  nlohmann::json footer;  // null unless finished
  // The host's processed results stored with the scan (PUT /scans/{id}/results/{name}),
  // by name; empty until a host uploads them.
  std::vector<std::string> results;
};

// A processed result the host may store with a scan: PUT /api/v1/scans/{id}/results/{name}.
// The list is fixed (no file name is ever formed from a client's string) and each name has
// its own size limit, checked before the body is read.
struct ResultKind {
  std::string_view name;          // "mesh.ply", "preview-front.png", ...
  std::string_view content_type;  // served with GET
  uint64_t max_bytes;
};
// Every name `mirrorscan process` writes that the device keeps: mesh.ply, the preview PNGs,
// measurements.json, summary.json.
const std::vector<ResultKind>& ResultKinds();
// The kind named `name`, or nullptr for anything not on the list.
const ResultKind* FindResultKind(std::string_view name);

// One stored result in GET /api/v1/scans/{id}/results.
struct ResultInfo {
  std::string name;
  uint64_t bytes = 0;
  std::string modified;  // UTC, "2026-11-24T02:56:40Z"
};

// One server-sent event on GET /api/v1/events: "event: <type>", "data: <ScanProgress>".
struct ScanEventMessage {
  std::string type;  // "state" or "progress"
  ScanProgress scan;
};

// Every 4xx/5xx body: {"api_version": 1, "error": "not_found", "message": "no scan ..."}.
struct ApiError {
  std::string error;    // a stable code: bad_request, unauthorized, forbidden, not_found, ...
  std::string message;  // one sentence naming the problem
};

void to_json(nlohmann::json& j, const ScanProgress& v);
void from_json(const nlohmann::json& j, ScanProgress& v);
void to_json(nlohmann::json& j, const DiskUse& v);
void from_json(const nlohmann::json& j, DiskUse& v);
void to_json(nlohmann::json& j, const DeviceStatus& v);
void from_json(const nlohmann::json& j, DeviceStatus& v);
void to_json(nlohmann::json& j, const ScanSummary& v);
void from_json(const nlohmann::json& j, ScanSummary& v);
void to_json(nlohmann::json& j, const ScanEventMessage& v);
void from_json(const nlohmann::json& j, ScanEventMessage& v);
void to_json(nlohmann::json& j, const ResultInfo& v);
void from_json(const nlohmann::json& j, ResultInfo& v);
void to_json(nlohmann::json& j, const ApiError& v);
void from_json(const nlohmann::json& j, ApiError& v);

// The error code for an HTTP status (400 → "bad_request", 401 → "unauthorized", ...).
std::string_view ErrorCode(int http_status);

}  // namespace mirrorscan::protocol

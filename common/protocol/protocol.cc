#include "common/protocol/protocol.h"

namespace mirrorscan::protocol {

bool IsValidScanId(std::string_view id) {
  constexpr size_t kIdLength = 21;
  if (id.size() != kIdLength) return false;
  for (size_t i = 0; i < id.size(); ++i) {
    const char c = id[i];
    if (i == 8) {
      if (c != 'T') return false;
    } else if (i == 15) {
      if (c != 'Z') return false;
    } else if (i == 16) {
      if (c != '-') return false;
    } else if (c < '0' || c > '9') {
      return false;
    }
  }
  return true;
}

void to_json(nlohmann::json& j, const ScanProgress& v) {
  j = {{"state", v.state},       {"scan_id", v.scan_id},
       {"progress", v.progress}, {"position_mm", v.position_mm},
       {"frames", v.frames},     {"peaks", v.peaks},
       {"dropped", v.dropped},   {"reason", v.reason}};
}

void from_json(const nlohmann::json& j, ScanProgress& v) {
  v.state = j.at("state").get<std::string>();
  v.scan_id = j.value("scan_id", "");
  v.progress = j.value("progress", 0.0);
  v.position_mm = j.value("position_mm", 0.0);
  v.frames = j.value("frames", uint64_t{0});
  v.peaks = j.value("peaks", uint64_t{0});
  v.dropped = j.value("dropped", uint64_t{0});
  v.reason = j.value("reason", "");
}

void to_json(nlohmann::json& j, const DiskUse& v) {
  j = {{"total_bytes", v.total_bytes},
       {"free_bytes", v.free_bytes},
       {"scans_bytes", v.scans_bytes},
       {"full", v.full},
       {"problem", v.problem}};
}

void from_json(const nlohmann::json& j, DiskUse& v) {
  v.total_bytes = j.value("total_bytes", uint64_t{0});
  v.free_bytes = j.value("free_bytes", uint64_t{0});
  v.scans_bytes = j.value("scans_bytes", uint64_t{0});
  v.full = j.value("full", false);
  v.problem = j.value("problem", "");
}

void to_json(nlohmann::json& j, const DeviceStatus& v) {
  j = {{"api_version", kApiVersion},
       {"board", v.board},
       {"firmware_version", v.firmware_version},
       {"calibration_sha256", v.calibration_sha256},
       {"calibration_problem", v.calibration_problem},
       {"cameras", v.cameras},
       {"scan", v.scan},
       {"disk", v.disk}};
}

void from_json(const nlohmann::json& j, DeviceStatus& v) {
  v.board = j.at("board").get<std::string>();
  v.firmware_version = j.value("firmware_version", "");
  v.calibration_sha256 = j.value("calibration_sha256", "");
  v.calibration_problem = j.value("calibration_problem", "");
  v.scan = j.at("scan").get<ScanProgress>();
  v.disk = j.value("disk", DiskUse{});
  v.cameras = j.value("cameras", std::vector<std::string>{});
}

void to_json(nlohmann::json& j, const ScanSummary& v) {
  j = {{"id", v.id},         {"state", v.state},    {"reason", v.reason}, {"created", v.created},
       {"frames", v.frames}, {"peaks", v.peaks},    {"bytes", v.bytes},   {"header", v.header},
       {"footer", v.footer}, {"results", v.results}};
}

void from_json(const nlohmann::json& j, ScanSummary& v) {
  v.id = j.at("id").get<std::string>();
  v.state = j.at("state").get<std::string>();
  v.reason = j.value("reason", "");
  v.created = j.value("created", "");
  v.frames = j.value("frames", uint64_t{0});
  v.peaks = j.value("peaks", uint64_t{0});
  v.bytes = j.value("bytes", uint64_t{0});
  v.header = j.value("header", nlohmann::json::object());
  v.footer = j.value("footer", nlohmann::json());
  v.results = j.value("results", std::vector<std::string>{});
}

const std::vector<ResultKind>& ResultKinds() {
  // Generous against what `process` writes for a body (a mesh of a few MB, previews and
  // JSON of some kB): room for finer meshes, a bound on what a host can make us store.
  constexpr uint64_t kMiB = 1u << 20;
  static const std::vector<ResultKind> kinds = {
      {"mesh.ply", "application/octet-stream", 64 * kMiB},
      {"preview-front.png", "image/png", 8 * kMiB},
      {"preview-back.png", "image/png", 8 * kMiB},
      {"preview-left.png", "image/png", 8 * kMiB},
      {"preview-right.png", "image/png", 8 * kMiB},
      {"preview-cloud-views.png", "image/png", 8 * kMiB},
      {"preview-cloud-cameras.png", "image/png", 8 * kMiB},
      {"preview-measurements.png", "image/png", 8 * kMiB},
      {"measurements.json", "application/json", 1 * kMiB},
      {"summary.json", "application/json", 1 * kMiB},
  };
  return kinds;
}

const ResultKind* FindResultKind(std::string_view name) {
  for (const ResultKind& kind : ResultKinds()) {
    if (kind.name == name) return &kind;
  }
  return nullptr;
}

void to_json(nlohmann::json& j, const ResultInfo& v) {
  j = {{"name", v.name}, {"bytes", v.bytes}, {"modified", v.modified}};
}

void from_json(const nlohmann::json& j, ResultInfo& v) {
  v.name = j.at("name").get<std::string>();
  v.bytes = j.value("bytes", uint64_t{0});
  v.modified = j.value("modified", "");
}

void to_json(nlohmann::json& j, const ScanEventMessage& v) {
  j = {{"type", v.type}, {"scan", v.scan}};
}

void from_json(const nlohmann::json& j, ScanEventMessage& v) {
  v.type = j.at("type").get<std::string>();
  v.scan = j.at("scan").get<ScanProgress>();
}

void to_json(nlohmann::json& j, const ApiError& v) {
  j = {{"api_version", kApiVersion}, {"error", v.error}, {"message", v.message}};
}

void from_json(const nlohmann::json& j, ApiError& v) {
  v.error = j.at("error").get<std::string>();
  v.message = j.value("message", "");
}

std::string_view ErrorCode(int http_status) {
  switch (http_status) {
    case 400:
      return "bad_request";
    case 401:
      return "unauthorized";
    case 403:
      return "forbidden";
    case 404:
      return "not_found";
    case 405:
      return "method_not_allowed";
    case 409:
      return "conflict";
    case 413:
      return "payload_too_large";
    case 414:
      return "uri_too_long";
    case 415:
      return "unsupported_media_type";
    case 429:
      return "too_many_requests";
    case 416:
      return "range_not_satisfiable";
    case 503:
      return "unavailable";
    default:
      return http_status >= 500 ? "internal_error" : "bad_request";
  }
}

}  // namespace mirrorscan::protocol

#include "firmware/board/board_config.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::board {
namespace {

std::string NonEmptyString(const JsonReader& r, const std::string& key) {
  std::string s = r.String(key);
  if (s.empty()) r.Fail(key, "must not be empty");
  return s;
}

BoardCamera ParseCamera(const JsonReader& r) {
  BoardCamera c;
  const std::string backend = r.Choice("backend", {"libcamera", "virtual", "replay"});
  if (backend == "libcamera") {
    r.AllowOnly(
        {"name", "backend", "id", "width", "height", "fps", "exposure_us", "gain", "buffer_count"});
    c.backend = CameraBackend::kLibcamera;
    c.id = NonEmptyString(r, "id");
  } else if (backend == "virtual") {
    r.AllowOnly(
        {"name", "backend", "id", "width", "height", "fps", "exposure_us", "gain", "buffer_count"});
    c.backend = CameraBackend::kVirtual;
    c.scene_camera = r.Integer("id", std::nullopt, 0, 63);
  } else {
    r.AllowOnly({"name", "backend", "path", "width", "height", "fps", "exposure_us", "gain",
                 "buffer_count"});
    c.backend = CameraBackend::kReplay;
    c.path = NonEmptyString(r, "path");
  }
  c.name = NonEmptyString(r, "name");
  c.config.width = r.Integer("width");
  c.config.height = r.Integer("height");
  c.config.fps = r.Number("fps");
  c.config.exposure_us = r.Integer("exposure_us");
  c.config.gain = r.Number("gain", 1.0);
  c.config.buffer_count = r.Integer("buffer_count", c.config.buffer_count);
  try {
    c.config.Validate();
  } catch (const hal::HardwareError& e) {
    // "camera.<key>: problem" -> "file: cameras[i].<key>: problem".
    const std::string message = e.what();
    const std::string prefix = "camera.";
    const size_t colon = message.find(": ");
    if (message.rfind(prefix, 0) == 0 && colon != std::string::npos) {
      r.Fail(message.substr(prefix.size(), colon - prefix.size()), message.substr(colon + 2));
    }
    throw ConfigError(r.file() + ": cameras: " + message);
  }
  return c;
}

std::vector<BoardCamera> ParseCameras(const JsonReader& board) {
  const std::vector<JsonReader> readers = board.Objects("cameras");
  if (readers.empty()) board.Fail("cameras", "at least one camera is required");
  std::vector<BoardCamera> cameras;
  std::set<std::string> names;
  std::set<std::string> sources;  // libcamera ids, virtual indices, replay paths
  for (const JsonReader& r : readers) {
    BoardCamera c = ParseCamera(r);
    if (!names.insert(c.name).second) r.Fail("name", "\"" + c.name + "\" is used twice");
    const std::string source = c.backend == CameraBackend::kLibcamera ? "libcamera:" + c.id
                               : c.backend == CameraBackend::kVirtual
                                   ? "virtual:" + std::to_string(c.scene_camera)
                                   : "replay:" + c.path.string();
    if (!sources.insert(source).second) {
      r.Fail(c.backend == CameraBackend::kReplay ? "path" : "id", "another camera already uses it");
    }
    cameras.push_back(std::move(c));
  }
  return cameras;
}

BoardDrive ParseDrive(const JsonReader& drive) {
  BoardDrive d;
  if (drive.Choice("backend", {"modbus", "virtual"}) == "virtual") {
    drive.AllowOnly({"backend"});
    d.backend = BoardDrive::Backend::kVirtual;
  } else {
    d.backend = BoardDrive::Backend::kModbus;
    d.modbus = hal::ParseModbusDriveConfig(drive);
  }
  return d;
}

ScanConfig ParseScan(const JsonReader& scan, const BoardDrive& drive) {
  scan.AllowOnly({"max_laser_on_s", "sweep_start_mm", "sweep_end_mm", "speed_mm_s",
                  "home_timeout_s", "camera_stall_ms"});
  ScanConfig s;
  s.max_laser_on_s = scan.Number("max_laser_on_s", std::nullopt, 0.1, 600.0);
  s.sweep_start_mm = scan.Number("sweep_start_mm");
  s.sweep_end_mm = scan.Number("sweep_end_mm");
  s.speed_mm_s = scan.Number("speed_mm_s", std::nullopt, 1e-3, 1e5);
  s.home_timeout_s = scan.Number("home_timeout_s", std::nullopt, 0.1, 600.0);
  s.camera_stall_ms = scan.Number("camera_stall_ms", s.camera_stall_ms, 50.0, 10000.0);
  if (s.sweep_start_mm == s.sweep_end_mm) {
    scan.Fail("sweep_end_mm", "must differ from sweep_start_mm");
  }
  if (drive.backend == BoardDrive::Backend::kModbus) {
    const hal::ModbusDriveConfig& m = drive.modbus;
    const std::string travel = "outside drive.travel_mm [" + std::to_string(m.travel_min_mm) +
                               ", " + std::to_string(m.travel_max_mm) + "]";
    for (const char* key : {"sweep_start_mm", "sweep_end_mm"}) {
      const double mm = scan.Number(key);
      if (mm < m.travel_min_mm || mm > m.travel_max_mm) scan.Fail(key, travel);
    }
    if (s.speed_mm_s > m.max_speed_mm_s) {
      scan.Fail("speed_mm_s",
                "exceeds drive.max_speed_mm_s (" + std::to_string(m.max_speed_mm_s) + ")");
    }
  }
  // A sweep the supervisor would always cut short is a configuration error.
  const double sweep_s = std::abs(s.sweep_end_mm - s.sweep_start_mm) / s.speed_mm_s;
  if (sweep_s > s.max_laser_on_s) {
    scan.Fail("max_laser_on_s", "shorter than the sweep (" + std::to_string(sweep_s) + " s)");
  }
  return s;
}

StoreConfig ParseStore(const JsonReader& store) {
  store.AllowOnly({"retention_scans"});
  StoreConfig s;
  s.retention_scans = store.Integer("retention_scans", std::nullopt, 1, 100000);
  return s;
}

ServiceConfig ParseService(const JsonReader& service) {
  service.AllowOnly({"listen", "token", "token_file", "auth_reads"});
  ServiceConfig s;
  s.listen = NonEmptyString(service, "listen");
  const size_t colon = s.listen.rfind(':');
  const std::string port = colon == std::string::npos ? "" : s.listen.substr(colon + 1);
  const bool digits = !port.empty() && port.size() <= 5 &&
                      port.find_first_not_of("0123456789") == std::string::npos;
  if (colon == 0 || !digits || std::stoi(port) < 1 || std::stoi(port) > 65535) {
    service.Fail("listen", "expected \"host:port\" with port 1..65535");
  }
  const bool has_token = service.Has("token");
  const bool has_token_file = service.Has("token_file");
  if (has_token == has_token_file) {
    service.Fail("token",
                 "give exactly one of \"token\" (a fixed development token) and "
                 "\"token_file\" (generated at first start)");
  }
  if (has_token) {
    s.token = service.String("token");
    if (!IsValidServiceToken(s.token)) {
      service.Fail("token", std::string("expected ") + kServiceTokenRule);
    }
  } else {
    s.token_file = NonEmptyString(service, "token_file");
    if (s.token_file.is_relative()) service.Fail("token_file", "expected an absolute path");
  }
  s.auth_reads = service.Bool("auth_reads", true);
  return s;
}

}  // namespace

bool IsValidServiceToken(std::string_view token) {
  if (token.size() < 16 || token.size() > 256) return false;
  for (const char c : token) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '.' || c == '_' || c == '~';
    if (!ok) return false;
  }
  return true;
}

BoardConfig BoardConfig::Parse(const nlohmann::json& json, const std::string& file) {
  if (!json.is_object()) throw ConfigError(file + ": expected a JSON object");
  const JsonReader r(json, file);
  r.AllowOnly({"board", "description", "cameras", "gpio", "drive", "peaks", "scan", "store",
               "service", "virtual",
               // The host's: host/calibration and host/board read them.
               "calibration", "reconstruction"});
  BoardConfig c;
  c.board = NonEmptyString(r, "board");
  c.description = r.String("description");
  c.cameras = ParseCameras(r);
  c.gpio = hal::ParseGpioConfig(r.Object("gpio"));
  c.drive = ParseDrive(r.Object("drive"));
  c.peaks = PeakParams::FromJson(r.Object("peaks"));
  c.scan = ParseScan(r.Object("scan"), c.drive);
  c.store = ParseStore(r.Object("store"));
  c.service = ParseService(r.Object("service"));
  const bool virtual_cameras = std::any_of(
      c.cameras.begin(), c.cameras.end(),
      [](const BoardCamera& camera) { return camera.backend == CameraBackend::kVirtual; });
  if (r.Has("virtual")) {
    const JsonReader v = r.Object("virtual");
    v.AllowOnly({"scene"});
    const std::filesystem::path scene = NonEmptyString(v, "scene");
    c.virtual_scene =
        scene.is_absolute() ? scene : std::filesystem::path(file).parent_path() / scene;
  } else if (virtual_cameras) {
    r.Fail("virtual",
           "required by the cameras with backend \"virtual\" (e.g. {\"scene\": "
           "\"scenes/mannequin.json\"})");
  }
  return c;
}

BoardConfig BoardConfig::Load(const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  return Parse(json, board_json.string());
}

}  // namespace mirrorscan::board

#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"
#include "common/peaks/peaks.h"
#include "firmware/hal/camera.h"
#include "firmware/hal/gpio_config.h"
#include "firmware/hal/modbus/modbus_drive_config.h"

namespace mirrorscan::board {

// Which Camera implementation a board.json camera asks for.
enum class CameraBackend { kLibcamera, kVirtual, kReplay };

// One entry of board.json's "cameras" list (docs/boards.md).
struct BoardCamera {
  std::string name;  // unique on the board; names the camera in scans and calibration
  CameraBackend backend = CameraBackend::kLibcamera;
  std::string id;              // libcamera: the camera id (string)
  int scene_camera = 0;        // virtual: index into the virtual cabinet's cameras
  std::filesystem::path path;  // replay: directory of *.pgm frames
  hal::CameraConfig config;    // validated (CameraConfig::Validate)
};

// "drive": a Modbus drive, or the firmware's in-process simulated drive.
struct BoardDrive {
  enum class Backend { kModbus, kVirtual };
  Backend backend = Backend::kModbus;
  hal::ModbusDriveConfig modbus;  // kModbus only
};

// "scan": the sweep and the safety supervisor's limits.
struct ScanConfig {
  double max_laser_on_s = 30.0;  // the supervisor switches the lasers off after this
  double sweep_start_mm = 0.0;
  double sweep_end_mm = 1800.0;
  double speed_mm_s = 100.0;
  double home_timeout_s = 30.0;
  double camera_stall_ms = 250.0;  // no frame for this long during a sweep is a fault
};

// "store": the on-device scan store.
struct StoreConfig {
  int retention_scans = 50;  // oldest completed scans beyond this are deleted
};

// "service": the device API (docs/device-api.md). Exactly one of `token` and `token_file`.
struct ServiceConfig {
  std::string listen;  // "host:port"
  // A fixed token in board.json: the virtual board's development token only, since a
  // token in a shipped file is no secret.
  std::string token;
  // A real board's token: generated at first start (mode 0600), then read at every start.
  std::filesystem::path token_file;
  // GET requests (scans, archives, events, calibration) need the token too; only a lab
  // that wants open reads sets it false (docs/device-api.md says what that exposes).
  bool auth_reads = true;
};

inline constexpr const char* kServiceTokenRule = "16 to 256 characters of A-Z a-z 0-9 - . _ ~";
// What a bearer token may be (kServiceTokenRule).
bool IsValidServiceToken(std::string_view token);

// A whole board.json. Every section is required; unknown keys anywhere are errors, and
// every error is a ConfigError naming the file and key ("board.json: cameras[1].fps: ...").
struct BoardConfig {
  std::string board;
  std::string description;
  std::vector<BoardCamera> cameras;
  hal::GpioConfig gpio;
  BoardDrive drive;
  PeakParams peaks;
  ScanConfig scan;
  StoreConfig store;
  ServiceConfig service;
  // "virtual": the virtual cabinet's scene file, resolved against board.json's folder.
  // Required when a camera has backend "virtual"; empty otherwise.
  std::filesystem::path virtual_scene;

  static BoardConfig Load(const std::filesystem::path& board_json);
  // `file` names the source in errors.
  static BoardConfig Parse(const nlohmann::json& json, const std::string& file);
};

}  // namespace mirrorscan::board

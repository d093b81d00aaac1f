#pragma once

// `mirrorscand --check` (docs/firmware.md): the board's hardware and the device's state
// checked once, one line per check, the way Horus's autocheck does before a scan: the
// cameras are there and stream, the lasers switch on and off (seen by a camera), the drive
// answers and homes, the data directory has room and takes a write, a calibration is
// stored and valid, the clock is sane. Nothing is changed but the slide's position.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "firmware/board/board_config.h"
#include "firmware/board/simulator.h"

namespace mirrorscan::app {

struct CheckResult {
  std::string name;  // "camera upper", "lasers", "drive", "disk", "calibration", "clock"
  bool ok = false;
  std::string detail;  // one line: what was measured, or what is wrong and what to do
};

struct SelfCheckOptions {
  std::filesystem::path board_file;
  std::filesystem::path data_dir;
  std::filesystem::path scene;  // virtual boards: replaces virtual.scene
  board::Simulator simulator;   // virtual boards: their drive and cameras
  uint64_t min_free_bytes = 64u << 20;
  // Virtual boards only, for the tests: the laser lines never go off once on.
  bool fault_lasers_stuck = false;
  // Virtual boards only: the simulated drive reads requests and never answers.
  bool fault_drive_silent = false;
};

// Runs every check (a device that cannot be built fails its line; the others still run)
// and reports each through `report` as it finishes.
std::vector<CheckResult> RunSelfCheck(const board::BoardConfig& config,
                                      const SelfCheckOptions& options,
                                      const std::function<void(const CheckResult&)>& report);

}  // namespace mirrorscan::app

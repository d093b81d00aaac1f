#pragma once
// The host's reading of a board.json (docs/boards.md): the sections only the PC uses, which
// the firmware (firmware/board) passes over, and the extractor's "peaks" for the host's
// offline tools. They live here rather than in common/config because only the host
// calibrates and reconstructs: the ARM build has no use for them, and common/ cannot name
// the host's types.
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "common/peaks/peaks.h"
#include "host/calibration/calibrate.h"
#include "host/reconstruction/bounding_cylinder.h"

namespace mirrorscan::host_board {

// From board.json's optional "reconstruction": {"bounding_cylinder": {"radius_mm",
// "core_radius_mm", "bottom_mm", "top_mm", "center_mm"}}; defaults for missing keys.
// ConfigError naming the file and key on a bad value.
reconstruction::BoundingCylinder BoundingCylinderFromBoard(const std::filesystem::path& board_json);

// The camera names from board.json's "cameras" and its optional "calibration" section
// (target, nominal mirrors, lens chessboard, limits: docs/calibration.md); defaults for
// missing keys. ConfigError naming the file and key on a bad value.
calibration::CalibrationSettings CalibrationSettingsFromBoard(
    const std::filesystem::path& board_json);
// The same from a parsed board.json; `file` names it in errors.
calibration::CalibrationSettings ParseCalibrationSettings(const nlohmann::json& board,
                                                          const std::string& file);

// How high the cabinet scans, as board.json states it: "scan" sweep_end_mm (the slide's
// readback at the sweep's end) and the mirrors' top ("calibration" mirror_bottom_mm +
// mirror_height_mm); each empty where the board does not say. The pose check's reach
// (host/pose) takes the calibration's own mirror corners first.
struct BoardReach {
  std::optional<double> sweep_end_mm;
  std::optional<double> mirror_top_mm;
};
BoardReach ReachFromBoard(const std::filesystem::path& board_json);

// The extractor's parameters from board.json's "peaks" (PeakParams::FromJson); defaults
// when it has none.
PeakParams PeakParamsFromBoard(const std::filesystem::path& board_json);

}  // namespace mirrorscan::host_board

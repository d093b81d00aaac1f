#include "host/board/board_json.h"

#include <algorithm>
#include <vector>

#include "common/config/json_reader.h"

namespace mirrorscan::host_board {

reconstruction::BoundingCylinder BoundingCylinderFromBoard(
    const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  const JsonReader root(json, board_json.string());
  reconstruction::BoundingCylinder c;
  if (!root.Has("reconstruction")) return c;
  const JsonReader r = root.Object("reconstruction");
  r.AllowOnly({"bounding_cylinder"});
  if (!r.Has("bounding_cylinder")) return c;
  const JsonReader b = r.Object("bounding_cylinder");
  b.AllowOnly({"radius_mm", "core_radius_mm", "bottom_mm", "top_mm", "center_mm"});
  c.radius_mm = b.Number("radius_mm", c.radius_mm, 1.0, 1e5);
  c.core_radius_mm = b.Number("core_radius_mm", std::min(c.core_radius_mm, c.radius_mm), 1.0, 1e5);
  if (c.core_radius_mm > c.radius_mm) b.Fail("core_radius_mm", "must not exceed radius_mm");
  c.bottom_mm = b.Number("bottom_mm", c.bottom_mm, -1e5, 1e5);
  c.top_mm = b.Number("top_mm", c.top_mm, -1e5, 1e5);
  if (c.top_mm <= c.bottom_mm) b.Fail("top_mm", "must be above bottom_mm");
  const std::vector<double> center = b.Numbers("center_mm", 2, std::vector<double>{0.0, 0.0});
  c.center_mm = {center[0], center[1]};
  return c;
}

calibration::CalibrationSettings ParseCalibrationSettings(const nlohmann::json& board,
                                                          const std::string& file) {
  const JsonReader root(board, file);
  calibration::CalibrationSettings s;
  for (const JsonReader& camera : root.Objects("cameras"))
    s.camera_names.push_back(camera.String("name"));
  if (!root.Has("calibration")) return s;
  const JsonReader r = root.Object("calibration");
  r.AllowOnly({"target", "target_id", "mirror_width_mm", "mirror_height_mm", "mirror_bottom_mm",
               "panel_offset_mm", "corner_xy_mm", "lens_chessboard", "limits"});
  if (r.Has("target")) s.target = TargetConfig::Parse(r.Object("target"));
  s.target_id = r.String("target_id", s.target_id);
  s.mirror_width_mm = r.Number("mirror_width_mm", s.mirror_width_mm, 10.0, 1e4);
  s.mirror_height_mm = r.Number("mirror_height_mm", s.mirror_height_mm, 10.0, 1e4);
  s.mirror_bottom_mm = r.Number("mirror_bottom_mm", s.mirror_bottom_mm, -1e4, 1e4);
  s.panel_offset_mm = r.Number("panel_offset_mm", s.panel_offset_mm, 0.0, 1000.0);
  const auto corner = r.Numbers(
      "corner_xy_mm", 2, std::vector<double>{s.corner_xy_mm.x(), s.corner_xy_mm.y()});
  s.corner_xy_mm = {corner[0], corner[1]};
  if (r.Has("lens_chessboard")) {
    const JsonReader b = r.Object("lens_chessboard");
    b.AllowOnly({"columns", "rows", "square_mm"});
    s.lens_chessboard.columns = b.Integer("columns", s.lens_chessboard.columns, 2, 100);
    s.lens_chessboard.rows = b.Integer("rows", s.lens_chessboard.rows, 2, 100);
    s.lens_chessboard.square_mm = b.Number("square_mm", s.lens_chessboard.square_mm, 1.0, 500.0);
  }
  if (r.Has("limits")) {
    const JsonReader l = r.Object("limits");
    l.AllowOnly({"max_rms_px", "min_markers_per_view", "min_contrast_dn", "max_edge_sigma_px",
                 "min_white_dn", "min_mirror_angle_deg", "max_mirror_angle_deg",
                 "max_mirror_tilt_deg", "max_corner_offset_mm", "max_yaw_deg", "verify_max_rms_px",
                 "max_panel_offset_error_mm", "min_lens_coverage"});
    calibration::CalibrationLimits& x = s.limits;
    x.max_rms_px = l.Number("max_rms_px", x.max_rms_px, 0.001, 100.0);
    x.min_markers_per_view =
        l.Integer("min_markers_per_view", x.min_markers_per_view, 4, kTargetMarkersPerPanel);
    x.min_contrast_dn = l.Number("min_contrast_dn", x.min_contrast_dn, 0.0, 255.0);
    x.max_edge_sigma_px = l.Number("max_edge_sigma_px", x.max_edge_sigma_px, 0.1, 100.0);
    x.min_white_dn = l.Number("min_white_dn", x.min_white_dn, 0.0, 255.0);
    x.min_mirror_angle_deg = l.Number("min_mirror_angle_deg", x.min_mirror_angle_deg, 1.0, 179.0);
    x.max_mirror_angle_deg =
        l.Number("max_mirror_angle_deg", x.max_mirror_angle_deg, x.min_mirror_angle_deg, 179.0);
    x.max_mirror_tilt_deg = l.Number("max_mirror_tilt_deg", x.max_mirror_tilt_deg, 0.0, 90.0);
    x.max_corner_offset_mm = l.Number("max_corner_offset_mm", x.max_corner_offset_mm, 0.0, 1e4);
    x.max_yaw_deg = l.Number("max_yaw_deg", x.max_yaw_deg, 0.0, 180.0);
    x.verify_max_rms_px = l.Number("verify_max_rms_px", x.verify_max_rms_px, 0.001, 100.0);
    x.max_panel_offset_error_mm =
        l.Number("max_panel_offset_error_mm", x.max_panel_offset_error_mm, 0.01, 1000.0);
    x.min_lens_coverage = l.Number("min_lens_coverage", x.min_lens_coverage, 0.0, 1.0);
  }
  return s;
}

calibration::CalibrationSettings CalibrationSettingsFromBoard(
    const std::filesystem::path& board_json) {
  return ParseCalibrationSettings(JsonReader::ParseFile(board_json), board_json.string());
}

BoardReach ReachFromBoard(const std::filesystem::path& board_json) {
  const nlohmann::json board = JsonReader::ParseFile(board_json);
  const JsonReader root(board, board_json.string());
  BoardReach reach;
  if (root.Has("scan") && root.Object("scan").Has("sweep_end_mm")) {
    reach.sweep_end_mm = root.Object("scan").Number("sweep_end_mm", std::nullopt, -1e5, 1e5);
  }
  if (root.Has("calibration")) {
    const JsonReader c = root.Object("calibration");
    if (c.Has("mirror_height_mm") && c.Has("mirror_bottom_mm")) {
      reach.mirror_top_mm = c.Number("mirror_bottom_mm", std::nullopt, -1e4, 1e4) +
                            c.Number("mirror_height_mm", std::nullopt, 10.0, 1e4);
    }
  }
  return reach;
}

PeakParams PeakParamsFromBoard(const std::filesystem::path& board_json) {
  const nlohmann::json board = JsonReader::ParseFile(board_json);
  const JsonReader root(board, board_json.string());
  return root.Has("peaks") ? PeakParams::FromJson(root.Object("peaks")) : PeakParams();
}

}  // namespace mirrorscan::host_board

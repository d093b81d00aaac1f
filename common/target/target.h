// The factory calibration target (the paper's Fig. 3), a physical object that both the
// calibration (host/calibration detects it) and the virtual cabinet (boards/virtual
// renders it) know: three flat white panels forming the sides of a vertical equilateral
// triangular prism, each carrying 16 ArUco markers (DICT_4X4_50), so that the centre view
// and both mirror views each see one panel.
//
// This is its geometry only: the panels, every marker's id and 3D corners. What the
// markers look like (their modules' bit patterns, the panels' albedo, the mesh) is the
// renderer's business and lives in boards/virtual/rendered_target.h.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"

namespace mirrorscan {

inline constexpr int kTargetPanels = 3;
inline constexpr int kTargetMarkerColumns = 2;
inline constexpr int kTargetMarkerRows = 8;
inline constexpr int kTargetMarkersPerPanel = kTargetMarkerColumns * kTargetMarkerRows;
inline constexpr int kTargetMarkers = kTargetPanels * kTargetMarkersPerPanel;
inline constexpr const char* kTargetDictionaryName = "DICT_4X4_50";
// A DICT_4X4_50 marker is 4 x 4 data modules inside one black border module each side.
inline constexpr int kTargetMarkerBits = 4;
inline constexpr int kTargetMarkerModules = kTargetMarkerBits + 2;

// The "target" object of a scene file or of board.json's calibration section. Every key
// is optional; defaults below.
struct TargetConfig {
  Eigen::Vector2d center_mm = Eigen::Vector2d::Zero();  // prism axis on the floor (x, y)
  double yaw_deg = 0.0;           // rotation about +z; 0: panel 0 faces the camera (-y)
  double bottom_mm = 200.0;       // height of the panels' lower edge
  double panel_width_mm = 420.0;  // also the side of the prism's equilateral cross-section
  double panel_height_mm = 1600.0;
  double marker_size_mm = 150.0;  // black outer square; at most 3/4 of a layout cell

  // Reads keys center_mm [x, y], yaw_deg, bottom_mm, panel_width_mm, panel_height_mm,
  // marker_size_mm; unknown keys and out-of-range values are ConfigErrors naming the key.
  static TargetConfig Parse(const JsonReader& reader);
};

// One panel's front face. origin is the bottom-left corner as seen from the front;
// right, up and normal (outward, towards the viewer) are unit and right-handed.
struct TargetPanel {
  Eigen::Vector3d origin, right, up, normal;
  double width = 0.0, height = 0.0;
};

// Corners in OpenCV order: top-left, top-right, bottom-right, bottom-left as seen from
// the panel's front.
struct TargetMarker {
  int id = 0;
  int panel = 0;
  std::array<Eigen::Vector3d, 4> corners;
  // The top-left corner's (u right, v up) in its panel, from the panel's origin.
  Eigen::Vector2d top_left_in_panel = Eigen::Vector2d::Zero();
};

// Panel 0 faces the camera (ids 0-15), panel 1 back-left (ids 16-31, seen in the left
// mirror), panel 2 back-right (ids 32-47). On each panel the markers sit centred in a
// 2-column x 8-row grid of cells, numbered row by row from the top-left as seen from the
// front, so every marker has at least one module of white quiet zone.
class CalibrationTarget {
 public:
  explicit CalibrationTarget(const TargetConfig& config);

  const TargetConfig& config() const { return config_; }
  const std::vector<TargetPanel>& panels() const { return panels_; }
  // Indexed by id.
  const std::vector<TargetMarker>& markers() const { return markers_; }

  // A point's (u right, v up) coordinates in a panel's plane, from its bottom-left corner.
  Eigen::Vector2d PanelCoordinates(int panel, const Eigen::Vector3d& point_in_world) const;

  // Dictionary, configuration, panels and every marker's id and 3D corners; written beside
  // rendered target images as the calibration's ground truth.
  nlohmann::json ToJson() const;

 private:
  TargetConfig config_;
  std::vector<TargetPanel> panels_;
  std::vector<TargetMarker> markers_;
};

}  // namespace mirrorscan

// The factory calibration target of the virtual cabinet (the paper's Fig. 3): three flat
// white panels forming the sides of a vertical equilateral triangular prism, each carrying
// 16 ArUco markers (DICT_4X4_50), so that the centre view and both mirror views each see
// one panel.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/mesh.h"
#include "common/config/json_reader.h"

namespace mirrorscan::virtual_cabinet {

inline constexpr double kTargetBlackAlbedo = 0.05;
inline constexpr double kTargetWhiteAlbedo = 0.85;
// Panel backs, edges and anything else of the target that is not a front face.
inline constexpr double kTargetBodyAlbedo = kTargetWhiteAlbedo;
inline constexpr double kTargetPanelThicknessMm = 10.0;
// A point counts as on a front face when within this distance of its plane; far above
// ray-tracing round-off, far below the panel thickness.
inline constexpr double kTargetSurfaceToleranceMm = 0.5;
inline constexpr int kTargetPanels = 3;
inline constexpr int kTargetMarkerColumns = 2;
inline constexpr int kTargetMarkerRows = 8;
inline constexpr int kTargetMarkersPerPanel = kTargetMarkerColumns * kTargetMarkerRows;
inline constexpr const char* kTargetDictionaryName = "DICT_4X4_50";

// The "target" object of a scene file. Every key is optional; defaults below.
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
  const std::vector<TargetMarker>& markers() const { return markers_; }

  // The three panels as closed boxes kTargetPanelThicknessMm thick, mitred where they
  // meet, front faces exactly on the panel planes; triangles CCW seen from outside.
  TriangleMesh Mesh() const;

  // Reflectance at a world point on a panel's front face (kTargetBlackAlbedo or
  // kTargetWhiteAlbedo); nullopt when the point is not on a front face (anywhere else on
  // the target is kTargetBodyAlbedo).
  std::optional<double> Albedo(const Eigen::Vector3d& point_in_world) const;

  // Mean reflectance over a square footprint of side `footprint_mm` centred on the point,
  // lying in the panel plane with sides along the panel's right/up, computed from the exact
  // area covered by black modules, so renders are alias-free. The part of the footprint
  // beyond the panel's edge is left out of the mean. nullopt as for Albedo.
  std::optional<double> AlbedoArea(const Eigen::Vector3d& point_in_world,
                                   double footprint_mm) const;

  // Dictionary, configuration, panels and every marker's id and 3D corners; written beside
  // rendered target images as the calibration's ground truth.
  nlohmann::json ToJson() const;

 private:
  // Panel whose front face holds the point, and the point's (u right, v up) coordinates in
  // it; nullopt when none does.
  struct PanelHit {
    int panel;
    Eigen::Vector2d uv;
  };
  std::optional<PanelHit> FindPanel(const Eigen::Vector3d& point_in_world) const;
  // Area of black inside the axis-aligned rectangle [u0,u1]x[v0,v1] of a panel.
  double BlackArea(int panel, double u0, double u1, double v0, double v1) const;

  // A marker's layout in its panel's (u, v) coordinates.
  struct MarkerLayout {
    double left = 0.0, top = 0.0;  // u of its left edge, v of its top edge
    double module = 0.0;           // side of one of its 6 x 6 modules (border included)
    std::array<std::array<bool, 6>, 6> black{};  // [row from top][column from left]
  };

  TargetConfig config_;
  std::vector<TargetPanel> panels_;
  std::vector<TargetMarker> markers_;
  std::vector<MarkerLayout> layouts_;  // parallel to markers_
};

}  // namespace mirrorscan::virtual_cabinet

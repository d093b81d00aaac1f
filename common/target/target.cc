#include "common/target/target.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include <Eigen/Geometry>

namespace mirrorscan {
namespace {

// A cell holds the marker's modules plus one white quiet module on each side.
constexpr double kMaxMarkerFill =
    static_cast<double>(kTargetMarkerModules) / (kTargetMarkerModules + 2);

constexpr std::array<const char*, kTargetPanels> kPanelNames = {"front", "back_left", "back_right"};

nlohmann::json ToJsonVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

TargetConfig TargetConfig::Parse(const JsonReader& reader) {
  reader.AllowOnly(
      {"center_mm", "yaw_deg", "bottom_mm", "panel_width_mm", "panel_height_mm", "marker_size_mm"});
  TargetConfig c;
  const std::vector<double> center =
      reader.Numbers("center_mm", 2, std::vector<double>{c.center_mm.x(), c.center_mm.y()});
  c.center_mm = {center[0], center[1]};
  c.yaw_deg = reader.Number("yaw_deg", c.yaw_deg, -360.0, 360.0);
  c.bottom_mm = reader.Number("bottom_mm", c.bottom_mm, 0.0, 5000.0);
  // The lower bounds keep the renderer's mitred panel boxes (10 mm thick) well formed.
  c.panel_width_mm = reader.Number("panel_width_mm", c.panel_width_mm, 100.0, 5000.0);
  c.panel_height_mm = reader.Number("panel_height_mm", c.panel_height_mm, 100.0, 5000.0);
  c.marker_size_mm = reader.Number("marker_size_mm", c.marker_size_mm, 1.0, 5000.0);
  // Each marker needs one module of white around it inside its layout cell, or the
  // detector may merge neighbours or lose it at the panel edge.
  const double cell =
      std::min(c.panel_width_mm / kTargetMarkerColumns, c.panel_height_mm / kTargetMarkerRows);
  const double limit = kMaxMarkerFill * cell;
  if (c.marker_size_mm > limit * (1.0 + 1e-12)) {
    std::ostringstream problem;
    problem << "must be at most " << limit << " (3/4 of the " << cell
            << " mm layout cell, to keep a white quiet zone), got " << c.marker_size_mm;
    reader.Fail("marker_size_mm", problem.str());
  }
  return c;
}

CalibrationTarget::CalibrationTarget(const TargetConfig& config) : config_(config) {
  const double w = config.panel_width_mm;
  const double h = config.panel_height_mm;
  const double ms = config.marker_size_mm;
  // Distance from the prism axis to each face of an equilateral prism with side w.
  const double apothem = w / (2.0 * std::sqrt(3.0));
  const Eigen::Vector3d center(config.center_mm.x(), config.center_mm.y(), config.bottom_mm);
  const double yaw = config.yaw_deg * std::numbers::pi / 180.0;
  // Front, back-left, back-right: outward normals 120 degrees apart.
  const std::array<double, kTargetPanels> offsets = {0.0, -2.0 * std::numbers::pi / 3.0,
                                                     2.0 * std::numbers::pi / 3.0};
  for (int p = 0; p < kTargetPanels; ++p) {
    const double phi = yaw + offsets[p];
    TargetPanel panel;
    panel.normal = Eigen::Vector3d(std::sin(phi), -std::cos(phi), 0.0);
    panel.up = Eigen::Vector3d::UnitZ();
    panel.right = panel.up.cross(panel.normal);  // so right x up = normal
    panel.origin = center + apothem * panel.normal - 0.5 * w * panel.right;
    panel.width = w;
    panel.height = h;
    panels_.push_back(panel);
  }

  const double cell_w = w / kTargetMarkerColumns;
  const double cell_h = h / kTargetMarkerRows;
  for (int p = 0; p < kTargetPanels; ++p) {
    const TargetPanel& panel = panels_[p];
    for (int row = 0; row < kTargetMarkerRows; ++row) {
      for (int col = 0; col < kTargetMarkerColumns; ++col) {
        // Centred in its cell: u of the left edge, v of the top edge.
        const double left = (col + 0.5) * cell_w - 0.5 * ms;
        const double top = h - (row + 0.5) * cell_h + 0.5 * ms;
        TargetMarker marker;
        marker.id = p * kTargetMarkersPerPanel + row * kTargetMarkerColumns + col;
        marker.panel = p;
        marker.top_left_in_panel = {left, top};
        const Eigen::Vector3d top_left = panel.origin + left * panel.right + top * panel.up;
        marker.corners = {top_left, top_left + ms * panel.right,
                          top_left + ms * panel.right - ms * panel.up, top_left - ms * panel.up};
        markers_.push_back(marker);
      }
    }
  }
}

Eigen::Vector2d CalibrationTarget::PanelCoordinates(int panel,
                                                    const Eigen::Vector3d& point_in_world) const {
  const TargetPanel& p = panels_.at(panel);
  const Eigen::Vector3d d = point_in_world - p.origin;
  return {d.dot(p.right), d.dot(p.up)};
}

nlohmann::json CalibrationTarget::ToJson() const {
  nlohmann::json json;
  json["dictionary"] = kTargetDictionaryName;
  json["marker_size_mm"] = config_.marker_size_mm;
  json["corner_order"] = "top-left, top-right, bottom-right, bottom-left seen from the front";
  json["config"] = {{"center_mm", {config_.center_mm.x(), config_.center_mm.y()}},
                    {"yaw_deg", config_.yaw_deg},
                    {"bottom_mm", config_.bottom_mm},
                    {"panel_width_mm", config_.panel_width_mm},
                    {"panel_height_mm", config_.panel_height_mm},
                    {"marker_size_mm", config_.marker_size_mm}};
  nlohmann::json panels = nlohmann::json::array();
  for (int p = 0; p < kTargetPanels; ++p) {
    const TargetPanel& panel = panels_[p];
    panels.push_back({{"index", p},
                      {"name", kPanelNames[p]},
                      {"origin", ToJsonVector(panel.origin)},
                      {"right", ToJsonVector(panel.right)},
                      {"up", ToJsonVector(panel.up)},
                      {"normal", ToJsonVector(panel.normal)},
                      {"width_mm", panel.width},
                      {"height_mm", panel.height}});
  }
  json["panels"] = panels;
  nlohmann::json markers = nlohmann::json::array();
  for (const TargetMarker& m : markers_) {
    nlohmann::json corners = nlohmann::json::array();
    for (const Eigen::Vector3d& c : m.corners) corners.push_back(ToJsonVector(c));
    markers.push_back({{"id", m.id}, {"panel", m.panel}, {"corners", corners}});
  }
  json["markers"] = markers;
  return json;
}

}  // namespace mirrorscan

#include "boards/virtual/target.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>

namespace mirrorscan::virtual_cabinet {
namespace {

constexpr int kMarkerBits = 4;             // DICT_4X4_50
constexpr int kModules = kMarkerBits + 2;  // one black border module each side
// A cell holds the marker's 6 modules plus one white quiet module on each side.
constexpr double kMaxMarkerFill = static_cast<double>(kModules) / (kModules + 2);

constexpr std::array<const char*, kTargetPanels> kPanelNames = {"front", "back_left", "back_right"};

nlohmann::json ToJsonVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Overlap length of [a0, a1] and [b0, b1].
double Overlap(double a0, double a1, double b0, double b1) {
  return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
}

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
  // The lower bounds keep the mitred panel boxes (kTargetPanelThicknessMm) well formed.
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

  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  const double cell_w = w / kTargetMarkerColumns;
  const double cell_h = h / kTargetMarkerRows;
  for (int p = 0; p < kTargetPanels; ++p) {
    const TargetPanel& panel = panels_[p];
    for (int row = 0; row < kTargetMarkerRows; ++row) {
      for (int col = 0; col < kTargetMarkerColumns; ++col) {
        MarkerLayout layout;
        layout.left = (col + 0.5) * cell_w - 0.5 * ms;
        layout.top = h - (row + 0.5) * cell_h + 0.5 * ms;
        layout.module = ms / kModules;

        TargetMarker marker;
        marker.id = p * kTargetMarkersPerPanel + row * kTargetMarkerColumns + col;
        marker.panel = p;
        const Eigen::Vector3d top_left =
            panel.origin + layout.left * panel.right + layout.top * panel.up;
        marker.corners = {top_left, top_left + ms * panel.right,
                          top_left + ms * panel.right - ms * panel.up, top_left - ms * panel.up};

        // Bits as OpenCV draws them: row-major from the top-left, 1 = white.
        const cv::Mat bits = cv::aruco::Dictionary::getBitsFromByteList(
            dictionary->bytesList.rowRange(marker.id, marker.id + 1), kMarkerBits);
        for (int r = 0; r < kModules; ++r) {
          for (int c = 0; c < kModules; ++c) {
            const bool border = r == 0 || c == 0 || r == kModules - 1 || c == kModules - 1;
            layout.black[r][c] = border || bits.at<unsigned char>(r - 1, c - 1) == 0;
          }
        }
        markers_.push_back(marker);
        layouts_.push_back(layout);
      }
    }
  }
}

TriangleMesh CalibrationTarget::Mesh() const {
  TriangleMesh mesh;
  const double t = kTargetPanelThicknessMm;
  // The back face is inset at both ends so the end faces lie in the bisector planes of
  // neighbouring panels: the boxes meet without poking through each other's fronts.
  const double inset = std::sqrt(3.0) * t;
  for (const TargetPanel& p : panels_) {
    const int base = static_cast<int>(mesh.vertices.size());
    const Eigen::Vector3d w = p.width * p.right;
    const Eigen::Vector3d h = p.height * p.up;
    const Eigen::Vector3d back0 = p.origin + inset * p.right - t * p.normal;
    const Eigen::Vector3d back1 = p.origin + w - inset * p.right - t * p.normal;
    // 0-3 front (bottom-left, bottom-right, top-right, top-left), 4-7 back likewise.
    mesh.vertices.insert(mesh.vertices.end(), {p.origin, p.origin + w, p.origin + w + h,
                                               p.origin + h, back0, back1, back1 + h, back0 + h});
    const std::array<Eigen::Vector3i, 12> faces = {
        Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(0, 2, 3),  // front
        Eigen::Vector3i(4, 6, 5), Eigen::Vector3i(4, 7, 6),  // back
        Eigen::Vector3i(0, 4, 5), Eigen::Vector3i(0, 5, 1),  // bottom
        Eigen::Vector3i(3, 2, 6), Eigen::Vector3i(3, 6, 7),  // top
        Eigen::Vector3i(0, 3, 4), Eigen::Vector3i(3, 7, 4),  // left end
        Eigen::Vector3i(1, 5, 2), Eigen::Vector3i(2, 5, 6),  // right end
    };
    for (const Eigen::Vector3i& f : faces) {
      mesh.triangles.push_back(f + Eigen::Vector3i::Constant(base));
    }
  }
  return mesh;
}

std::optional<CalibrationTarget::PanelHit> CalibrationTarget::FindPanel(
    const Eigen::Vector3d& point_in_world) const {
  std::optional<PanelHit> best;
  double best_distance = kTargetSurfaceToleranceMm;
  for (int p = 0; p < kTargetPanels; ++p) {
    const TargetPanel& panel = panels_[p];
    const Eigen::Vector3d d = point_in_world - panel.origin;
    const double distance = std::abs(panel.normal.dot(d));
    const double u = panel.right.dot(d);
    const double v = panel.up.dot(d);
    // Nearest plane wins: near a prism edge a point is within tolerance of both panels.
    if (distance <= best_distance && u >= 0.0 && u <= panel.width && v >= 0.0 &&
        v <= panel.height) {
      best = PanelHit{p, Eigen::Vector2d(u, v)};
      best_distance = distance;
    }
  }
  return best;
}

std::optional<double> CalibrationTarget::Albedo(const Eigen::Vector3d& point_in_world) const {
  const std::optional<PanelHit> hit = FindPanel(point_in_world);
  if (!hit) return std::nullopt;
  const double u = hit->uv.x();
  const double v = hit->uv.y();
  for (int k = 0; k < kTargetMarkersPerPanel; ++k) {
    const MarkerLayout& m = layouts_[hit->panel * kTargetMarkersPerPanel + k];
    const double side = kModules * m.module;
    if (u < m.left || u >= m.left + side || v > m.top || v <= m.top - side) continue;
    const int col = std::clamp(static_cast<int>((u - m.left) / m.module), 0, kModules - 1);
    const int row = std::clamp(static_cast<int>((m.top - v) / m.module), 0, kModules - 1);
    return m.black[row][col] ? kTargetBlackAlbedo : kTargetWhiteAlbedo;
  }
  return kTargetWhiteAlbedo;
}

double CalibrationTarget::BlackArea(int panel, double u0, double u1, double v0, double v1) const {
  double area = 0.0;
  for (int k = 0; k < kTargetMarkersPerPanel; ++k) {
    const MarkerLayout& m = layouts_[panel * kTargetMarkersPerPanel + k];
    const double side = kModules * m.module;
    if (Overlap(u0, u1, m.left, m.left + side) <= 0.0 ||
        Overlap(v0, v1, m.top - side, m.top) <= 0.0) {
      continue;
    }
    for (int r = 0; r < kModules; ++r) {
      const double dv = Overlap(v0, v1, m.top - (r + 1) * m.module, m.top - r * m.module);
      if (dv <= 0.0) continue;
      for (int c = 0; c < kModules; ++c) {
        if (!m.black[r][c]) continue;
        area += dv * Overlap(u0, u1, m.left + c * m.module, m.left + (c + 1) * m.module);
      }
    }
  }
  return area;
}

std::optional<double> CalibrationTarget::AlbedoArea(const Eigen::Vector3d& point_in_world,
                                                    double footprint_mm) const {
  const std::optional<PanelHit> hit = FindPanel(point_in_world);
  if (!hit) return std::nullopt;
  const TargetPanel& panel = panels_[hit->panel];
  const double half = 0.5 * std::max(footprint_mm, 0.0);
  const double u0 = std::max(hit->uv.x() - half, 0.0);
  const double u1 = std::min(hit->uv.x() + half, panel.width);
  const double v0 = std::max(hit->uv.y() - half, 0.0);
  const double v1 = std::min(hit->uv.y() + half, panel.height);
  const double area = (u1 - u0) * (v1 - v0);
  // A vanishing footprint has no area to average over: it is a point sample.
  if (!(area > 1e-12)) return Albedo(point_in_world);
  const double black_fraction = std::clamp(BlackArea(hit->panel, u0, u1, v0, v1) / area, 0.0, 1.0);
  return kTargetWhiteAlbedo + (kTargetBlackAlbedo - kTargetWhiteAlbedo) * black_fraction;
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

}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/rendered_target.h"

#include <algorithm>
#include <cmath>

#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>

namespace mirrorscan::virtual_cabinet {
namespace {

constexpr int kModules = kTargetMarkerModules;

// Overlap length of [a0, a1] and [b0, b1].
double Overlap(double a0, double a1, double b0, double b1) {
  return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
}

}  // namespace

RenderedTarget::RenderedTarget(const TargetConfig& config) : CalibrationTarget(config) {
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  for (const TargetMarker& marker : markers()) {
    MarkerLayout layout;
    layout.left = marker.top_left_in_panel.x();
    layout.top = marker.top_left_in_panel.y();
    layout.module = config.marker_size_mm / kModules;
    // Bits as OpenCV draws them: row-major from the top-left, 1 = white.
    const cv::Mat bits = cv::aruco::Dictionary::getBitsFromByteList(
        dictionary->bytesList.rowRange(marker.id, marker.id + 1), kTargetMarkerBits);
    for (int r = 0; r < kModules; ++r) {
      for (int c = 0; c < kModules; ++c) {
        const bool border = r == 0 || c == 0 || r == kModules - 1 || c == kModules - 1;
        layout.black[r][c] = border || bits.at<unsigned char>(r - 1, c - 1) == 0;
      }
    }
    layouts_.push_back(layout);
  }
}

TriangleMesh RenderedTarget::Mesh() const {
  TriangleMesh mesh;
  const double t = kTargetPanelThicknessMm;
  // The back face is inset at both ends so the end faces lie in the bisector planes of
  // neighbouring panels: the boxes meet without poking through each other's fronts.
  const double inset = std::sqrt(3.0) * t;
  for (const TargetPanel& p : panels()) {
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

std::optional<RenderedTarget::PanelHit> RenderedTarget::FindPanel(
    const Eigen::Vector3d& point_in_world) const {
  std::optional<PanelHit> best;
  double best_distance = kTargetSurfaceToleranceMm;
  for (int p = 0; p < kTargetPanels; ++p) {
    const TargetPanel& panel = panels()[p];
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

std::optional<double> RenderedTarget::Albedo(const Eigen::Vector3d& point_in_world) const {
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

double RenderedTarget::BlackArea(int panel, double u0, double u1, double v0, double v1) const {
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

std::optional<double> RenderedTarget::AlbedoArea(const Eigen::Vector3d& point_in_world,
                                                 double footprint_mm) const {
  const std::optional<PanelHit> hit = FindPanel(point_in_world);
  if (!hit) return std::nullopt;
  const TargetPanel& panel = panels()[hit->panel];
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

}  // namespace mirrorscan::virtual_cabinet

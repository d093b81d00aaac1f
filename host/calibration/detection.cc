#include "host/calibration/detection.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "host/calibration/checks.h"
#include "host/calibration/markers.h"

namespace mirrorscan::calibration {
namespace internal {
namespace {

MarkerDetectorOptions DetectorOptions(const CalibrationTarget& target) {
  MarkerDetectorOptions options;
  options.markers_per_panel = kTargetMarkersPerPanel;
  for (const auto& m : target.markers()) {
    std::array<Eigen::Vector2d, 4> layout;
    for (int c = 0; c < 4; ++c) layout[c] = target.PanelCoordinates(m.panel, m.corners[c]);
    options.layout_mm.push_back(layout);
  }
  return options;
}

CameraData Detect(const CameraImage& image, const CalibrationTarget& target) {
  if (image.gray.empty() || image.gray.type() != CV_8UC1) {
    throw std::invalid_argument("camera " + image.name + ": expected an 8-bit grayscale image");
  }
  CameraData data;
  data.name = image.name;
  data.width = image.gray.cols;
  data.height = image.gray.rows;
  data.report.name = image.name;
  if (image.lens) {
    if (image.lens->width != data.width || image.lens->height != data.height) {
      throw std::invalid_argument("camera " + image.name + ": the lens calibration is for " +
                                  std::to_string(image.lens->width) + "x" +
                                  std::to_string(image.lens->height) + " images, this image is " +
                                  std::to_string(data.width) + "x" + std::to_string(data.height));
    }
    data.lens = image.lens;
  }
  const auto detections = DetectTargetMarkers(image.gray, DetectorOptions(target));
  std::vector<uint8_t> levels(image.gray.begin<uint8_t>(), image.gray.end<uint8_t>());
  std::nth_element(levels.begin(), levels.begin() + levels.size() * 99 / 100, levels.end());
  data.report.white_dn = levels[levels.size() * 99 / 100];
  for (int v = 0; v < kViews; ++v) {
    ViewReport& report = data.report.views[v];
    report.view = static_cast<ViewId>(v);
    report.rejected = detections[v].rejected;
    ViewPoints& points = data.views[v];
    std::vector<bool> seen(kTargetMarkersPerPanel, false);
    for (const DetectedMarker& m : detections[v].markers) {
      const auto& truth = target.markers()[m.id];
      report.found.push_back(m.id);
      seen[m.id % kTargetMarkersPerPanel] = true;
      report.contrast_dn += m.contrast_dn / detections[v].markers.size();
      report.edge_sigma_px += m.edge_sigma_px / detections[v].markers.size();
      for (int c = 0; c < 4; ++c) {
        points.in_world.push_back(truth.corners[c]);
        points.in_panel.push_back(target.PanelCoordinates(v, truth.corners[c]));
        points.pixels.push_back(m.corners[c]);
        const Eigen::Vector2d from = m.corners[c], to = m.corners[(c + 1) % 4];
        for (const Eigen::Vector2d& p : m.edge_points[c]) {
          points.edges.push_back({truth.corners[c], truth.corners[(c + 1) % 4],
                                  (p - from).dot(to - from) / (to - from).squaredNorm(), p});
        }
      }
    }
    for (int i = 0; i < kTargetMarkersPerPanel; ++i) {
      if (!seen[i]) report.missing.push_back(v * kTargetMarkersPerPanel + i);
    }
    report.observed = points.pixels;
  }
  std::vector<Eigen::Vector2d> support =
      image.lens ? image.lens_support_px : std::vector<Eigen::Vector2d>{};
  for (const ViewPoints& v : data.views)
    support.insert(support.end(), v.pixels.begin(), v.pixels.end());
  data.report.coverage = LensCoverage::Of(support, data.width, data.height);
  data.report.coverage.lens_fixed = image.lens.has_value();
  return data;
}

}  // namespace

std::vector<CameraData> DetectAll(const std::vector<CameraImage>& images,
                                  const CalibrationSettings& settings,
                                  const CalibrationTarget& target, CalibrationResult& result,
                                  bool& solvable) {
  if (images.empty()) throw std::invalid_argument("no camera image given");
  std::vector<CameraData> data;
  solvable = true;
  for (const CameraImage& image : images) {
    if (std::find(settings.camera_names.begin(), settings.camera_names.end(), image.name) ==
        settings.camera_names.end()) {
      throw std::invalid_argument("camera \"" + image.name + "\" is not in the board's cameras");
    }
    data.push_back(Detect(image, target));
    solvable = CheckDetections(data.back(), settings.limits, result) && solvable;
    result.cameras.push_back(data.back().report);
  }
  return data;
}

}  // namespace internal

LensCoverage LensCoverage::Of(const std::vector<Eigen::Vector2d>& pixels, int width, int height) {
  LensCoverage coverage;
  for (const Eigen::Vector2d& p : pixels) {
    const int column = static_cast<int>(std::floor((p.x() + 0.5) * kColumns / width));
    const int row = static_cast<int>(std::floor((p.y() + 0.5) * kRows / height));
    if (column < 0 || column >= kColumns || row < 0 || row >= kRows) continue;
    ++coverage.points[row * kColumns + column];
  }
  const auto covered =
      std::count_if(coverage.points.begin(), coverage.points.end(), [](int n) { return n > 0; });
  coverage.fraction = static_cast<double>(covered) / coverage.points.size();
  return coverage;
}

}  // namespace mirrorscan::calibration

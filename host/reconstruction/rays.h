#pragma once
// Rays (docs/reconstruction.md, stage 2): the cabinet as the rays meet it — each camera's
// mirror regions, the mirrors' planes and rectangles, the panels — and every peak's ray,
// undistorted and back-projected once for the laser fit and the hypotheses.
#include <array>
#include <optional>
#include <vector>

#include "common/config/calibration.h"
#include "common/geometry/plane.h"
#include "common/scan_format/scan_format.h"
#include "host/calibration/laser_height.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// A view region's outline cut by every image column: where the vertical line through the
// column crosses the outline, rows ascending. A pixel is inside when an odd number of them
// lie above it (the even–odd rule of CalibrationView::Contains, along the column).
class RegionColumns {
 public:
  RegionColumns() = default;
  RegionColumns(const CalibrationView& view, int width) : crossings_(width) {
    const std::vector<Eigen::Vector2d>& outline = view.outline_px;
    for (int u = 0; u < width; ++u) {
      for (size_t i = 0, j = outline.size() - 1; i < outline.size(); j = i++) {
        const Eigen::Vector2d& a = outline[i];
        const Eigen::Vector2d& b = outline[j];
        if ((a.x() > u) == (b.x() > u)) continue;
        crossings_[u].push_back(a.y() + (u - a.x()) * (b.y() - a.y()) / (b.x() - a.x()));
      }
      std::sort(crossings_[u].begin(), crossings_[u].end());
    }
  }
  bool Contains(int u, double v) const {
    if (u < 0 || u >= static_cast<int>(crossings_.size())) return false;
    const std::vector<double>& c = crossings_[u];
    return (std::upper_bound(c.begin(), c.end(), v) - c.begin()) % 2 == 1;
  }

 private:
  std::vector<std::vector<double>> crossings_;
};

// The calibrated cabinet by FrameRecord::camera.
struct Geometry {
  std::vector<const CalibrationCamera*> cameras;
  std::vector<std::array<const CalibrationView*, 2>> mirror_views;
  std::vector<std::array<RegionColumns, 2>> mirror_regions;  // the same, by column
  std::array<Plane, 2> mirrors;
  std::vector<PlanarRectangle> mirror_rectangles;  // empty without corners
  std::vector<PlanarRectangle> panels;             // empty without corners
};

// The archive's cameras and their mirror regions (archive_check.h's errors), the mirrors,
// and, when the calibration has the mirrors' corners, their rectangles and the panels
// beside them (else a warning: rays through both mirrors are not followed).
Geometry CabinetGeometry(const ScanArchive& archive, const Calibration& calibration,
                         const ReconstructOptions& options, ReconstructSummary* summary);

// Every used peak's ray in the world (nullopt where undistortion fails), by peak index.
std::vector<std::optional<Ray3d>> PeakRays(const Geometry& g, const ScanArchive& archive,
                                           const PeakTable& table, int threads);

}  // namespace mirrorscan::reconstruction

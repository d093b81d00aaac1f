#include "host/reconstruction/rays.h"

#include <algorithm>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/archive_check.h"

namespace mirrorscan::reconstruction {
namespace {
constexpr double kPanelEdgeMm = 40.0;
}  // namespace

Geometry CabinetGeometry(const ScanArchive& archive, const Calibration& calibration,
                         const ReconstructOptions& options, ReconstructSummary* summary) {
  Geometry g;
  g.cameras = CamerasOf(archive, calibration);
  g.mirror_views = MirrorViewsOf(g.cameras, calibration);
  g.mirror_regions.resize(g.cameras.size());
  for (size_t c = 0; c < g.cameras.size(); ++c)
    if (g.cameras[c])
      for (int m = 0; m < 2; ++m)
        g.mirror_regions[c][m] =
            RegionColumns(*g.mirror_views[c][m], g.cameras[c]->camera.intrinsics.width);
  for (int m = 0; m < 2; ++m) g.mirrors[m] = calibration.mirrors[m].plane;
  if (std::all_of(calibration.mirrors.begin(), calibration.mirrors.end(),
                  [](const CalibrationMirror& m) { return m.corners_mm.size() == 4; })) {
    for (const CalibrationMirror& m : calibration.mirrors) {
      g.mirror_rectangles.push_back(MirrorRectangle(
          m.name, m.plane, {m.corners_mm[0], m.corners_mm[1], m.corners_mm[2], m.corners_mm[3]}));
    }
    g.panels =
        LaserCabinetFromCalibration(calibration, "calibration", options.panel_margin_mm).panels;
    // A peak on a panel's last pixels (its outer or top edge, blurred, or a calibration a
    // few mm off) has a ray that just misses the rectangle; without the panel as a way it
    // came about, another laser's point in front of the panel took it (cylinder 850: 594
    // points 380-730 mm off the body on f12, all at the image's left and right edges).
    // Nothing of the subject is out there, so the panels reach a little further here.
    for (PlanarRectangle& panel : g.panels) {
      panel.width += kPanelEdgeMm;
      panel.height += kPanelEdgeMm;
    }
  } else {
    summary->warnings.push_back(
        "the calibration has no mirror corners: rays through both mirrors are not followed");
  }
  return g;
}

std::vector<std::optional<Ray3d>> PeakRays(const Geometry& g, const ScanArchive& archive,
                                           const PeakTable& table, int threads) {
  std::vector<std::optional<Ray3d>> rays(table.peaks.size());
  std::vector<std::optional<CameraRays>> camera_rays(g.cameras.size());
  for (size_t c = 0; c < g.cameras.size(); ++c)
    if (g.cameras[c]) camera_rays[c] = g.cameras[c]->camera.RaysThroughPixels();
  ParallelFor(archive.frames.size(), threads, [&](size_t begin, size_t end) {
    for (size_t f = begin; f < end; ++f) {
      if (!table.used[f]) continue;
      const CameraRays& camera = *camera_rays[archive.frames[f].camera];
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i)
        rays[i] = camera.Through({table.peaks[i].u, table.peaks[i].v});
    }
  });
  return rays;
}

}  // namespace mirrorscan::reconstruction

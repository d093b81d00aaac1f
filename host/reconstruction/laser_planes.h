#pragma once
// Laser planes per frame (docs/reconstruction.md, stage 1): the fit of the laser lines on
// the panels beside the mirrors (host/calibration/laser_height), or the slide readback
// where the panels cannot be used.
#include <array>
#include <optional>
#include <vector>

#include "common/config/calibration.h"
#include "common/geometry/plane.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/archive_check.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

struct LaserPlanes {
  std::vector<std::array<Plane, kMaxLasers>> per_frame;  // by archive frame index
  std::vector<bool> valid;
  int count = 1;
};

// Laser planes of every frame: the panel lines' fit, or the slide readback where that is
// impossible (no mirror corners, too few panel points, options.laser_height_from_panels
// off; the summary's laser_height says which and why). The fit is given only the peaks
// whose ray (`rays`, by peak) meets a panel before any mirror, and the peaks it takes as a
// panel's line are marked (PeakState::panel). ReconstructError when there are no heights.
LaserPlanes FitLaserPlanes(const ScanArchive& archive, const Calibration& calibration,
                           const std::vector<const CalibrationCamera*>& cameras,
                           const ReconstructOptions& options,
                           const std::vector<std::optional<Ray3d>>& rays, int threads,
                           PeakTable* table, ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

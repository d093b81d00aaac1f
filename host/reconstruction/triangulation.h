#pragma once
// Stages 1-2 of docs/reconstruction.md up to the rules: the archive checked against the
// calibration, its peaks, their rays, the laser planes of every frame and every peak's
// hypotheses. Reconstruct() goes on from here; the rules' tests start here too.
#include "common/config/calibration.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/laser_planes.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/rays.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

struct Triangulation {
  Geometry geometry;
  PeakTable table;
  LaserPlanes planes;
  Hypotheses hyp;
};

// Throws what CheckArchive, ReadPeaks, FitLaserPlanes and Hypothesize throw. The stages'
// times go to `timer` (read, rays, laser heights, triangulation).
Triangulation Triangulate(const ScanArchive& archive, const Calibration& calibration,
                          const ReconstructOptions& options, int threads, StageTimer* timer,
                          ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

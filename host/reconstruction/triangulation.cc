#include "host/reconstruction/triangulation.h"

#include <optional>
#include <utility>
#include <vector>

#include "host/reconstruction/archive_check.h"
#include "host/reconstruction/laser_sequence.h"
#include "host/reconstruction/still_peaks.h"

namespace mirrorscan::reconstruction {

Triangulation Triangulate(const ScanArchive& archive, const Calibration& calibration,
                          const ReconstructOptions& options, int threads, StageTimer* timer,
                          ReconstructSummary* summary) {
  CheckArchive(archive, calibration, options, summary);
  Geometry geometry = CabinetGeometry(archive, calibration, options, summary);
  PeakTable table = ReadPeaks(archive, threads, summary);
  summary->dropped_still = MarkStillPeaks(threads, &table);
  timer->Lap("read");
  timer->Start("rays");
  // Each peak undistorted and back-projected once, for the laser fit and the hypotheses; a
  // still peak's ray is left out of both.
  std::vector<std::optional<Ray3d>> rays = PeakRays(geometry, archive, table, threads);
  for (size_t i = 0; i < rays.size(); ++i)
    if (table.peaks[i].still) rays[i].reset();
  timer->Lap("rays");
  timer->Start("laser heights");
  LaserPlanes planes = FitLaserPlanes(archive, calibration, geometry.cameras, options, rays,
                                      threads, &table, summary);
  timer->Lap("laser heights");
  timer->Start("triangulation");
  Hypotheses hyp = Hypothesize(archive, geometry, planes, options, rays, threads, &table, summary);
  MarkLaserSequence(table, planes, threads, &hyp);
  timer->Lap("triangulation");
  return Triangulation{std::move(geometry), std::move(table), std::move(planes), std::move(hyp)};
}

}  // namespace mirrorscan::reconstruction

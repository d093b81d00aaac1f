#include "host/reconstruction/reconstruct.h"

#include <cstdint>
#include <vector>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/filters.h"
#include "host/reconstruction/free_space.h"
#include "host/reconstruction/icp.h"
#include "host/reconstruction/normals.h"
#include "host/reconstruction/point_grid.h"
#include "host/reconstruction/rules/column_count.h"
#include "host/reconstruction/rules/cylinder.h"
#include "host/reconstruction/rules/label_vote.h"
#include "host/reconstruction/rules/stereo.h"
#include "host/reconstruction/rules/volume.h"
#include "host/reconstruction/surface_check.h"
#include "host/reconstruction/triangulation.h"

namespace mirrorscan::reconstruction {

namespace {

void CountDecisions(const std::vector<PeakState>& peaks, ReconstructSummary* summary) {
  for (const PeakState& p : peaks) {
    if (p.chosen < 0) continue;
    if (p.rule == Rule::kStereo) ++summary->decided_by_stereo;
    if (p.rule == Rule::kCylinder) ++summary->decided_by_cylinder;
    if (p.rule == Rule::kVolume) ++summary->decided_by_volume;
    if (p.rule == Rule::kColumnCount) ++summary->decided_by_column_count;
    if (p.rule == Rule::kLabelVote) ++summary->decided_by_label_vote;
  }
}

void CountPoints(const PointCloud& cloud, size_t cameras, int lasers, ReconstructSummary* summary) {
  summary->points_per_camera.assign(cameras, 0);
  summary->points_per_view.assign(kViews, 0);
  summary->points_per_laser.assign(lasers, 0);
  for (const CloudPoint& cp : cloud.points) {
    ++summary->points_per_camera[cp.camera];
    ++summary->points_per_view[static_cast<int>(cp.view)];
    ++summary->points_per_laser[cp.laser];
    if (cp.view == PointView::kLeftRight || cp.view == PointView::kRightLeft)
      ++summary->double_bounce;
  }
}

}  // namespace

const char* PointViewName(PointView view) {
  switch (view) {
    case PointView::kCenter:
      return "center";
    case PointView::kLeft:
      return "left";
    case PointView::kRight:
      return "right";
    case PointView::kLeftRight:
      return "left-right";
    case PointView::kRightLeft:
      return "right-left";
  }
  return "?";
}

const char* DecidedByName(DecidedBy rule) {
  switch (rule) {
    case DecidedBy::kCylinder:
      return "cylinder";
    case DecidedBy::kVolume:
      return "volume";
    case DecidedBy::kColumnCount:
      return "column_count";
    case DecidedBy::kLabelVote:
      return "label_vote";
    case DecidedBy::kStereo:
      return "stereo";
  }
  return "?";
}

Reconstruction Reconstruct(const ScanArchive& archive, const Calibration& calibration,
                           const ReconstructOptions& options) {
  options.Validate();
  Reconstruction result;
  ReconstructSummary& summary = result.summary;
  StageTimer timer(&summary, options.progress);
  const int threads = ResolveThreads(options.threads);
  Triangulation t = Triangulate(archive, calibration, options, threads, &timer, &summary);
  std::vector<PeakState>& peaks = t.table.peaks;

  // The correspondence rules in their order (docs/reconstruction.md, stages 2-4): each
  // decides only the peaks the ones before it left open.
  timer.Start("correspondence");
  DecideByOneHypothesis(threads, &peaks);
  if (options.stereo) {
    ConfirmByStereo(archive, t.table, t.planes.per_frame, options.stereo_max_mm, threads, &t.hyp);
    DecideByStereo(t.hyp, threads, &peaks);
    timer.Lap("stereo");
  }
  DecideByCore(t.hyp, options.cylinder, threads, &peaks);
  DecideByVolume(&peaks, t.hyp, options.cylinder, t.geometry, threads);
  DecideByColumnCount(&t.table, t.hyp, t.planes.count, threads);
  DecideByLabelVote(t.hyp, options, threads, &t.table, &summary);
  CountDecisions(peaks, &summary);
  timer.Lap("correspondence");
  if (options.free_space_check) {
    timer.Start("free space");
    DropPointsSeenThrough(t.geometry, archive, t.table, t.hyp, options, threads, &peaks,
                          &summary.dropped_seen_through);
    timer.Lap("free space");
  }

  timer.Start("filtering");
  DropBackground(t.hyp, &peaks, &summary);
  Grid grid(t.table, t.hyp, threads);
  grid.Link(options.label_max_row_step_px, options.label_max_frame_step_px, threads);
  const FilteredGrid filtered =
      FilterGrid(archive, t.table, t.geometry.cameras.size(), options, threads, &grid, &summary);
  timer.Lap("filtering");
  timer.Start("normals");
  PointNotes notes;
  result.cloud =
      PointsWithNormals(archive, t.table, grid, filtered, options, threads, &notes, &summary);
  timer.Lap("normals");
  if (options.surface_check) {
    const SurfaceDrops drops = DropOffSurface(options, threads, notes, &result.cloud.points);
    summary.dropped_off_surface = drops.weak;
    summary.dropped_outlier += drops.suspect;
    summary.dropped_flat_off_surface = drops.flat;
    timer.Lap("surface check");
  }
  CountPoints(result.cloud, t.geometry.cameras.size(), t.planes.count, &summary);
  if (options.icp) {
    timer.Start("icp");
    summary.icp = RefineViews(&result.cloud);
    timer.Lap("icp");
  }
  summary.points = result.cloud.points.size();
  timer.Start("done");
  return result;
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/filters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/voxel_box.h"

namespace mirrorscan::reconstruction {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
// The 3×3 average's neighbours lie within this of the point (one surface).
constexpr double kSmoothMaxMm = 10.0;

// Per camera and voxel (10 mm): the best ray–plane angle (its sine) of that camera's
// points there.
class AngleGrid {
 public:
  AngleGrid(const BoundingCylinder& c, size_t cameras)
      : box_(c, 10.0), cells_(cameras, std::vector<float>(box_.Voxels(), 0.0f)) {}
  void Add(size_t camera, const Eigen::Vector3d& point, float sin_angle) {
    if (const auto i = box_.Index(point)) {
      cells_[camera][*i] = std::max(cells_[camera][*i], sin_angle);
    }
  }
  // The best sine another camera has at the point.
  float BestOther(size_t camera, const Eigen::Vector3d& point) const {
    const auto i = box_.Index(point);
    float best = 0;
    if (!i) return best;
    for (size_t c = 0; c < cells_.size(); ++c)
      if (c != camera) best = std::max(best, cells_[c][*i]);
    return best;
  }

 private:
  VoxelBox box_;
  std::vector<std::vector<float>> cells_;
};

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

void DropFlatRays(const ReconstructOptions& options, Grid* grid, ReconstructSummary* summary) {
  const double min_sin = std::sin(options.min_ray_plane_angle_deg * kDegToRad);
  for (GridPoint& gp : grid->points) {
    if (gp.sin_angle < min_sin) {
      gp.keep = false;
      ++summary->dropped_flat_angle;
    }
  }
}

// Where several cameras see the same surface, the one meeting the laser planes more
// squarely: depth error grows as 1 / tan(angle).
void DropWhereAnotherCameraIsSquarer(const ScanArchive& archive, const PeakTable& table,
                                     size_t cameras, const ReconstructOptions& options, Grid* grid,
                                     ReconstructSummary* summary) {
  AngleGrid angles(options.cylinder, cameras);
  for (const GridPoint& gp : grid->points)
    if (gp.keep)
      angles.Add(archive.frames[table.peaks[gp.peak].frame].camera, gp.point, gp.sin_angle);
  for (GridPoint& gp : grid->points) {
    if (!gp.keep) continue;
    const size_t camera = archive.frames[table.peaks[gp.peak].frame].camera;
    if (angles.BestOther(camera, gp.point) > options.prefer_camera_ratio * gp.sin_angle) {
      gp.keep = false;
      ++summary->dropped_other_camera;
    }
  }
}

// Per point, the kept columns to its stripe's nearer end (up to stripe_end_columns + 2),
// decided on the whole stripe before any of it is dropped.
std::vector<int> StripeEndDistances(const Grid& grid, const ReconstructOptions& options,
                                    int threads) {
  std::vector<int> end_distance(grid.points.size(), 0);
  const int end_limit = std::max(1, options.stripe_end_columns) + 2;
  ParallelFor(grid.points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid.points[i];
      if (!gp.keep) continue;
      end_distance[i] =
          std::min(RunLength(grid, gp, -1, end_limit), RunLength(grid, gp, +1, end_limit));
    }
  });
  return end_distance;
}

void DropStripeEnds(const std::vector<int>& end_distance, const ReconstructOptions& options,
                    Grid* grid, ReconstructSummary* summary) {
  for (size_t i = 0; i < grid->points.size(); ++i) {
    if (grid->points[i].keep && end_distance[i] < options.stripe_end_columns) {
      grid->points[i].keep = false;
      ++summary->dropped_stripe_end;
    }
  }
}

// Outliers: the second difference along the column and frame directions.
void FlagOutliers(const ReconstructOptions& options, int threads, Grid* grid,
                  ReconstructSummary* summary) {
  std::vector<double> residual(grid->points.size(), -1.0);
  ParallelFor(grid->points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid->points[i];
      if (!gp.keep) continue;
      double best = std::numeric_limits<double>::infinity();
      bool isolated = true;
      for (const auto& [du, df] : {std::pair{1, 0}, std::pair{0, 1}}) {
        const int32_t a = grid->Neighbour(gp, du, df);
        const int32_t b = grid->Neighbour(gp, -du, -df);
        if (a >= 0 || b >= 0) isolated = false;
        if (a < 0 || b < 0) continue;
        // Less a share of the chord: a curved surface sampled coarsely (successive frames far
        // apart where the plane grazes it) bends away from the chord's midpoint by chord² / 8R.
        const double chord = (grid->points[a].point - grid->points[b].point).norm();
        const double off =
            (gp.point - 0.5 * (grid->points[a].point + grid->points[b].point)).norm();
        best = std::min(best, std::max(0.0, off - options.outlier_chord_share * chord));
      }
      if (isolated) {
        residual[i] = std::numeric_limits<double>::infinity();
      } else if (std::isfinite(best)) {
        residual[i] = best;
      }
    }
  });
  std::vector<double> all;
  for (const double r : residual)
    if (r >= 0 && std::isfinite(r)) all.push_back(r);
  // Gross errors only: the surface's own bends (edges, folds) stay.
  const double limit =
      std::max(options.outlier_min_mm, options.outlier_sigmas * 1.4826 * Median(all));
  // With the surface check, a flagged point stays a suspect until the confident points
  // around it have had their say: 1,711 of the mannequin's 2,139 flagged points, most of
  // them stripe ends, lie within 0.5 mm of its surface (docs/reconstruction.md).
  for (size_t i = 0; i < grid->points.size(); ++i) {
    if (residual[i] <= limit) continue;
    if (options.surface_check) {
      grid->points[i].suspect = true;
    } else {
      grid->points[i].keep = false;
      ++summary->dropped_outlier;
    }
  }
}

void ClipToCylinder(const BoundingCylinder& cylinder, Grid* grid, ReconstructSummary* summary) {
  for (GridPoint& gp : grid->points) {
    if (gp.keep && !cylinder.Contains(gp.point)) {
      gp.keep = false;
      ++summary->dropped_outside;
    }
  }
}

// The paper's 3×3 average in (column, frame), within one surface. Neighbours come in
// opposite pairs only, so the average stays centred on the point: one-sided at a stripe's
// end or the first frame of a surface it would pull the point along the surface (up to
// half a frame's slide travel off its laser plane) and, on a curved one, off it.
std::vector<Eigen::Vector3d> Smooth3x3(const Grid& grid, bool smooth, int threads) {
  std::vector<Eigen::Vector3d> smoothed(grid.points.size());
  auto usable = [&](const GridPoint& gp, int32_t q) {
    return q >= 0 && (grid.points[q].point - gp.point).norm() <= kSmoothMaxMm;
  };
  ParallelFor(grid.points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid.points[i];
      smoothed[i] = gp.point;
      if (!gp.keep || gp.suspect || !smooth) continue;
      Eigen::Vector3d sum = gp.point;
      int n = 1;
      for (const auto& [du, df] :
           {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
        const int32_t a = grid.Neighbour(gp, du, df);
        const int32_t b = grid.Neighbour(gp, -du, -df);
        if (!usable(gp, a) || !usable(gp, b)) continue;
        sum += grid.points[a].point + grid.points[b].point;
        n += 2;
      }
      smoothed[i] = sum / n;
    }
  });
  return smoothed;
}

}  // namespace

void DropBackground(const Hypotheses& hyp, std::vector<PeakState>* peaks,
                    ReconstructSummary* summary) {
  for (PeakState& p : *peaks) {
    if (p.chosen < 0) continue;
    const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
    if (h.floor) ++summary->dropped_floor;
    if (h.panel) ++summary->dropped_panel;
    if (h.Background()) p.chosen = -1;
  }
}

FilteredGrid FilterGrid(const ScanArchive& archive, const PeakTable& table, size_t cameras,
                        const ReconstructOptions& options, int threads, Grid* grid,
                        ReconstructSummary* summary) {
  DropFlatRays(options, grid, summary);
  if (options.prefer_camera_ratio > 0 && cameras > 1)
    DropWhereAnotherCameraIsSquarer(archive, table, cameras, options, grid, summary);
  FilteredGrid filtered;
  filtered.end_distance = StripeEndDistances(*grid, options, threads);
  if (options.drop_stripe_ends) DropStripeEnds(filtered.end_distance, options, grid, summary);
  if (options.remove_outliers) FlagOutliers(options, threads, grid, summary);
  if (options.clip_to_cylinder) ClipToCylinder(options.cylinder, grid, summary);
  filtered.smoothed = Smooth3x3(*grid, options.smooth_3x3, threads);
  return filtered;
}

}  // namespace mirrorscan::reconstruction

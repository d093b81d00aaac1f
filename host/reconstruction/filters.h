#pragma once
// Filters (docs/reconstruction.md, stage 6), each switchable in ReconstructOptions.
#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "common/scan_format/scan_format.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/point_grid.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// The floor and the panels decide a peak but are not the subject: such peaks are undecided
// again (dropped.floor, dropped.panel).
void DropBackground(const Hypotheses& hyp, std::vector<PeakState>* peaks,
                    ReconstructSummary* summary);

// Per grid point, what the normals and the confidence need of the filters.
struct FilteredGrid {
  std::vector<int> end_distance;          // kept columns to the stripe's nearer end
  std::vector<Eigen::Vector3d> smoothed;  // the place after the 3×3 average
};

// On the linked grid, in this order: rays flatter than min_ray_plane_angle_deg to their
// plane (dropped.flat_angle); where prefer_camera_ratio is set, a camera's points where
// another meets the planes that much more squarely (dropped.other_camera); with
// drop_stripe_ends, the stripes' last columns (dropped.stripe_end); outliers by the second
// difference along column and frame (dropped.outlier, or GridPoint::suspect for the surface
// check to judge); points outside the cylinder (dropped.outside_volume); then the 3×3
// average. `cameras`: the archive's camera count.
FilteredGrid FilterGrid(const ScanArchive& archive, const PeakTable& table, size_t cameras,
                        const ReconstructOptions& options, int threads, Grid* grid,
                        ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

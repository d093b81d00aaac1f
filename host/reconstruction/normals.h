#pragma once
// Normals and confidence (docs/reconstruction.md, stages 7-8): the kept grid points as the
// cloud's points.
#include <cstdint>
#include <vector>

#include "common/scan_format/scan_format.h"
#include "host/reconstruction/filters.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/point_grid.h"
#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// Every kept grid point with its normal from the (column, frame) grid (the cross product of
// the column and the frame direction, oriented towards the viewpoint; with only the
// stripe's direction known, the normal orthogonal to it closest to the ray) and its
// confidence (peak score × the ray's angle to the plane × the distance to the stripe's
// end). Points under options.min_confidence are dropped (dropped.low_confidence);
// `notes` gets, per point, what the surface check needs.
struct PointNotes {
  std::vector<uint8_t> suspect;  // the outlier test flagged it
  std::vector<float> sin_angle;  // of its ray to its laser plane
};
PointCloud PointsWithNormals(const ScanArchive& archive, const PeakTable& table, const Grid& grid,
                             const FilteredGrid& filtered, const ReconstructOptions& options,
                             int threads, PointNotes* notes, ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

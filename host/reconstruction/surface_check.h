#pragma once
// The surface check (docs/reconstruction.md, "The surface check"; options.surface_check).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "host/reconstruction/normals.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

// Points the check dropped: weak ones (dropped.off_surface), the outlier test's suspects
// (counted as outliers) and flat rays another camera contradicts (dropped.flat_off_surface).
struct SurfaceDrops {
  size_t weak = 0, suspect = 0, flat = 0;
};

// ReconstructOptions::surface_check, for the weak points (confidence below
// surface_check_confidence) and the outlier test's suspects (`suspect`, one flag per point):
// a weak point is dropped where it lies off the plane of the confident points around it, or,
// decided only by the column count or the vote, where none is near; a suspect is kept only
// close to that plane; a point whose ray meets its plane flatter than flat_check_deg is
// dropped where it lies off the plane of the confident points of other cameras that meet
// theirs flat_check_ratio times more squarely. The confident points that are not suspect
// are indexed in a grid of
// cells as large as the radius (counting sort), so a point's neighbours are in its 27 cells.
// The points left keep their order.
SurfaceDrops DropOffSurface(const ReconstructOptions& options, int threads, const PointNotes& notes,
                            std::vector<CloudPoint>* points);

}  // namespace mirrorscan::reconstruction

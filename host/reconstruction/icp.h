#pragma once
// Optional rigid refinement of the cloud's views and cameras against each other.
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

// Each (camera, view) group of points against the groups placed before it (Open3D's
// point-to-plane ICP within max_distance_mm): the first camera's centre view is the anchor,
// then the other cameras' centre views, then the mirror views. A group's correction is
// applied only when it overlaps (fitness ≥ 0.2) and lowers the residual by at least 10 %;
// every step is reported.
IcpSummary RefineViews(PointCloud* cloud, double max_distance_mm = 3.0);

}  // namespace mirrorscan::reconstruction

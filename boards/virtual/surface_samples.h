#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "boards/virtual/renderer.h"

namespace mirrorscan::virtual_cabinet {

// A point on the subject's true surface and whether the cabinet can scan it: some camera
// sees it (directly or in one mirror) and a laser reaches it, within the sweep's heights.
struct TruthSurfaceSample {
  Eigen::Vector3d point_in_world;
  Eigen::Vector3d normal;  // outward
  bool visible = false;
};

// Samples the subject's surface about one point per spacing² of area (area-weighted,
// deterministic for a seed) and decides for each whether the cabinet can scan it.
std::vector<TruthSurfaceSample> SampleSubjectSurface(const Renderer& renderer, double spacing_mm,
                                                     uint64_t seed = 1);

}  // namespace mirrorscan::virtual_cabinet

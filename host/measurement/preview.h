#pragma once

#include <opencv2/core.hpp>

#include "host/measurement/measure.h"
#include "host/measurement/section.h"

namespace mirrorscan::measurement {

// A front view of the mesh (orthographic, from the subject's front, its left on the
// image's right) with each measured contour and landmark drawn on the body and named.
// BGR, `height_px` high.
cv::Mat RenderPreview(const TriangleMesh& mesh, const BodyMeasurements& body, int height_px = 1000);

}  // namespace mirrorscan::measurement

// The calibration's pass/fail checks, each failure with its advice: the images' quality,
// the lens's coverage, the cabinet's geometry, the reprojection. Internal to
// host/calibration.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/plane.h"
#include "host/calibration/calibrate.h"
#include "host/calibration/detection.h"

namespace mirrorscan::calibration::internal {

// One number printed with a printf format, for the checks' limits and advice.
std::string Format(const char* format, double value);

// The image-quality checks and their advice; true when every view can be solved.
bool CheckDetections(const CameraData& data, const CalibrationLimits& limits,
                     CalibrationResult& result);

// The lens model rests on data over enough of the image (limits.min_lens_coverage).
void CheckCoverage(const CameraReport& report, const CalibrationLimits& limits,
                   CalibrationResult& result);

// The mirrors' rectangles: from where the two planes meet, nominal width and height.
std::array<std::vector<Eigen::Vector3d>, 2> MirrorCorners(const std::array<Plane, 2>& mirrors,
                                                          const CalibrationSettings& s);

// The calibrated mirrors make a plausible cabinet: their opening angle, standing vertical,
// meeting where the target says and square to it.
void CheckCabinet(const std::array<Plane, 2>& mirrors, const CalibrationSettings& s,
                  CalibrationResult& result);

// Each view's corners lie within `limit` (RMS) of where the model puts them; `what` says
// which model, in the failure.
void AddRmsChecks(const std::vector<CameraReport>& cameras, double limit, const char* what,
                  CalibrationResult& result);

}  // namespace mirrorscan::calibration::internal

// The target found in each camera's image, view by view: the corners and marker edges the
// calibration's steps fit to, with the image's report. Internal to host/calibration.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/target/target.h"
#include "host/calibration/calibrate.h"

namespace mirrorscan::calibration::internal {

// A point found on a marker's edge: the edge runs from a to b on the target, the point
// lies at about a + t (b - a).
struct EdgePoint {
  Eigen::Vector3d a, b;
  double t = 0.0;
  Eigen::Vector2d pixel;
};

// Every corner of one view: where the target has it and where the image shows it.
struct ViewPoints {
  std::vector<Eigen::Vector3d> in_world;
  std::vector<Eigen::Vector2d> in_panel;  // (right, up) in mm on its panel
  std::vector<Eigen::Vector2d> pixels;
  std::vector<EdgePoint> edges;
};

struct CameraData {
  std::string name;
  int width = 0, height = 0;
  std::optional<CameraIntrinsics> lens;  // fixed, from a lens calibration
  std::array<ViewPoints, kViews> views;
  CameraReport report;
};

// Detects the target in every image and checks each image's quality (checks.h), adding
// the cameras' reports, checks and failures to `result`; `solvable` is false when a view
// has fewer markers than a pose needs. std::invalid_argument on a camera the board does
// not name or an image that is not 8-bit grayscale.
std::vector<CameraData> DetectAll(const std::vector<CameraImage>& images,
                                  const CalibrationSettings& settings,
                                  const CalibrationTarget& target, CalibrationResult& result,
                                  bool& solvable);

}  // namespace mirrorscan::calibration::internal

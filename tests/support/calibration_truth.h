// How far an estimated calibration is from the virtual cabinet's truth where the scanner
// uses it: at every stripe point of a whole sweep (both cameras, every view, every
// column a stripe crosses), not only at the calibration target's markers.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "common/config/calibration.h"
#include "common/geometry/camera.h"

namespace mirrorscan::test_support {

// One truth stripe point: where the renderer puts the stripe centre in the image (u, v)
// and the 3D point on the laser plane and the surface.
struct TruthSample {
  int camera = 0;
  int frame = 0;
  int laser = 0;
  virtual_cabinet::View view = virtual_cabinet::View::kCenter;
  Eigen::Vector2d pixel;
  Eigen::Vector3d point_in_world;
};

// Every truth point of the scene's sweep, every `frame_step`-th frame.
std::vector<TruthSample> SweepTruth(const virtual_cabinet::Scene& scene, int frame_step = 1);

// Per camera and view: where the estimate projects the true 3D point against the true
// pixel, and where the estimate's ray through the true pixel (reflected at the estimated
// mirror in a mirror view) meets the true laser plane against the true point.
struct ViewAgreement {
  std::string camera, view;
  size_t points = 0;
  double rms_px = 0.0, p99_px = 0.0, max_px = 0.0;
  double rms_mm = 0.0, p99_mm = 0.0, max_mm = 0.0;
  // Beyond 400 px from the image centre, where the lens model matters most.
  size_t outer_points = 0;
  double outer_rms_px = 0.0;
};

// Double-bounce points (left-right, right-left) are left out: the calibration's views are
// the centre and one mirror. Level lasers only (the true plane is the one through the
// point with the lasers' normal). Cameras the calibration does not have are left out.
std::vector<ViewAgreement> CompareWithTruth(const Calibration& estimate,
                                            const virtual_cabinet::Scene& scene,
                                            const std::vector<TruthSample>& truth);

// A Markdown table of the above.
std::string FormatAgreement(const std::vector<ViewAgreement>& rows);

// Googletest checks (and a printed line each) of every camera's rotation, centre,
// intrinsics and distortion and every mirror plane of `estimate` against `truth`, within
// what the factory flow reaches (docs/calibration.md).
void ExpectParametersMatchTruth(const Calibration& estimate, const Calibration& truth);

}  // namespace mirrorscan::test_support

namespace mirrorscan::test_support {

// The factory's lens step on the virtual cabinet, as the ctest fixture cabinet_lens makes
// it (tests/support/cabinet-lens: `mirrorscan sim chessboard`, then calibrate-intrinsics on
// each camera's captures) into the build tree's test-data/lens/. Throws when the fixture
// has not run or the scene's camera is not the one it calibrated.
struct CabinetLens {
  std::filesystem::path captures_dir;  // the PNGs
  std::filesystem::path intrinsics_json;
  CameraIntrinsics intrinsics;
  std::vector<Eigen::Vector2d> support_px;
};
CabinetLens LensOf(const virtual_cabinet::Scene& scene, int camera);

}  // namespace mirrorscan::test_support

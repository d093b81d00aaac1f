// Mirror-cabinet calibration from one image of the three-panel target per camera (the
// paper's three steps): per-view camera models, mirror planes as mid-planes between the
// centre and reflected focal points, then a joint refinement of everything with Ceres.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core/mat.hpp>

#include "common/config/calibration.h"
#include "common/target/target.h"
#include "host/calibration/markers.h"

namespace mirrorscan::calibration {

// Pass/fail limits; keys of board.json's calibration.limits.
struct CalibrationLimits {
  double max_rms_px = 0.25;             // per view, after refinement
  int min_markers_per_view = 4;         // whole markers; a mirror's edge cuts some off
  double min_contrast_dn = 40.0;        // black border to white surround
  double max_edge_sigma_px = 1.2;       // blur of the marker edges (sharp: 0.8)
  double min_white_dn = 60.0;           // brightest percent of the image
  double min_mirror_angle_deg = 115.0;  // opening angle between the mirrors
  double max_mirror_angle_deg = 125.0;
  double max_mirror_tilt_deg = 1.0;    // mirrors stand vertical
  double max_corner_offset_mm = 20.0;  // mirrors' meeting line from its nominal place
  double max_yaw_deg = 1.0;            // cabinet symmetry axis from world +y
  double verify_max_rms_px = 0.5;      // --verify: stored calibration against a new image
  // calibrate-lasers: a panel measured further than this from panel_offset_mm is out of place.
  double max_panel_offset_error_mm = 1.0;
  // Share of the image's cells (16 x 12) holding at least one point the lens model was
  // fitted to (chessboard corners of the lens calibration, target corners): distortion is
  // only known where there are data, and the cabinet uses the whole image. The target
  // alone covers 22-25 %, a lens calibration from LensCalibrationPoses' 30 captures 90 %.
  // Below this the lens is refused (docs/calibration.md, "Lens over the whole field").
  double min_lens_coverage = 0.85;
};

// board.json's "calibration" section (every key optional) plus the camera names; read by
// host/board/board_json.h.
struct CalibrationSettings {
  std::vector<std::string> camera_names;
  TargetConfig target;
  std::string target_id = "3panel-aruco48";
  // Nominal reflecting rectangle, for the view regions (docs/boards.md's build drawing).
  double mirror_width_mm = 1000.0;
  double mirror_height_mm = 2100.0;
  double mirror_bottom_mm = 0.0;
  double panel_offset_mm =
      6.0;  // nominal; one target image cannot see it, a laser sweep measures it
  Eigen::Vector2d corner_xy_mm{0.0, 900.0};  // where the mirrors meet, nominal
  // The chessboard held in front of each camera for the lens step
  // (scripts/factory-calibrate --chessboard, calibrate-intrinsics).
  struct LensChessboard {
    int columns = 11, rows = 8;  // inner corners
    double square_mm = 25.0;
  } lens_chessboard;
  CalibrationLimits limits;
};

struct CameraImage {
  std::string name;
  cv::Mat gray;  // 8-bit, one channel
  // The lens from a separate calibration (calibrate-intrinsics): held fixed, so that the
  // model holds where the chessboard was and the target is not. Without it the target
  // alone sets the lens, which it supports only where its markers are.
  std::optional<CameraIntrinsics> lens;
  std::vector<Eigen::Vector2d> lens_support_px;  // the points the lens was fitted to
};

// Where in the image the lens model rests on data: a grid of cells, each counting the
// points (chessboard and target corners) in it.
struct LensCoverage {
  static constexpr int kColumns = 16, kRows = 12;
  std::array<int, kColumns * kRows> points{};
  double fraction = 0.0;  // of cells with at least one point
  bool lens_fixed = false;

  static LensCoverage Of(const std::vector<Eigen::Vector2d>& pixels, int width, int height);
};

struct ViewReport {
  ViewId view = ViewId::kCenter;
  std::vector<int> found, missing;
  int rejected = 0;
  double contrast_dn = 0.0, edge_sigma_px = 0.0;
  double rms_before_px = 0.0;  // model of steps 1 and 2 (or the stored calibration in verify)
  double rms_after_px = 0.0, max_after_px = 0.0;
  std::vector<Eigen::Vector2d> observed, reprojected;  // corners, after refinement
};

struct CameraReport {
  std::string name;
  double white_dn = 0.0;  // the level of the brightest percent of the image
  std::array<ViewReport, kViews> views;
  LensCoverage coverage;
};

struct Check {
  std::string name;
  double value = 0.0;
  std::string limit;
  bool ok = true;
};

struct CalibrationResult {
  bool ok = false;
  // One line each: what failed, and what to do about it.
  std::vector<std::string> failures;
  std::optional<Calibration> calibration;  // absent when nothing could be solved
  std::vector<CameraReport> cameras;
  std::vector<Check> checks;

  nlohmann::json ReportJson() const;
};

CalibrationResult Calibrate(const std::vector<CameraImage>& images,
                            const CalibrationSettings& settings);

// Detects the target in fresh images and measures how far its corners lie from where
// `existing` puts them, per view; a view beyond limits.verify_max_rms_px has changed.
CalibrationResult Verify(const std::vector<CameraImage>& images,
                         const CalibrationSettings& settings, const Calibration& existing);

// The image with found corners (green circles), reprojected ones (red crosses), each
// offset magnified 50 times (red line), each view's RMS, and the lens coverage: cells
// without data shaded red.
cv::Mat DrawReport(const CameraImage& image, const CameraReport& report);

}  // namespace mirrorscan::calibration

#pragma once

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/geometry/camera.h"

namespace mirrorscan {

// Bad input to the intrinsics calibration (an unreadable image, no board found, images of
// different sizes, too few views); the message names the image or the option.
class IntrinsicsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The printed pattern. A chessboard counts inner corners (OpenCV's 9x6 sample board has
// 10 × 7 squares); a ChArUco board counts squares, as cv::aruco::CharucoBoard does.
struct CalibrationPattern {
  enum class Kind { kChessboard, kCharuco };
  Kind kind = Kind::kChessboard;
  int columns = 9;  // inner corners (chessboard) or squares (ChArUco) along x
  int rows = 6;
  double square_mm = 25.0;
  double marker_mm = 0.0;                  // ChArUco only
  std::string dictionary = "DICT_4X4_50";  // ChArUco only

  // Throws IntrinsicsError naming the option.
  void Validate() const;
  // "9x6" → {9, 6}; throws IntrinsicsError naming `option` otherwise.
  static std::pair<int, int> ParseSize(const std::string& text, const std::string& option);
};

// Board corners found in one image: pixel positions and the matching board points (mm,
// z = 0).
struct PatternView {
  std::string image;
  std::vector<cv::Point2f> corners_px;
  std::vector<cv::Point3f> corners_on_board_mm;
  double rms_px = 0.0;  // this view's reprojection RMS after calibration
};

struct IntrinsicsResult {
  cv::Size image_size;
  CameraIntrinsics intrinsics;  // K and (k1, k2, p1, p2, k3)
  double rms_px = 0.0;          // over all corners of all views
  std::vector<PatternView> views;
  CalibrationPattern pattern;
};

// Corners of the pattern in one grayscale image (chessboard: findChessboardCorners refined
// by cornerSubPix, as OpenCV's calibration sample does; ChArUco: markers, then the
// interpolated chessboard corners). Throws IntrinsicsError naming `image_name` when the
// board is not found.
PatternView DetectPattern(const cv::Mat& gray, const CalibrationPattern& pattern,
                          const std::string& image_name);

// Called after each image with (images done, images total, image).
using IntrinsicsProgress = std::function<void(size_t, size_t, const std::string&)>;

// Detects the pattern in every image and runs cv::calibrateCamera (k1, k2, p1, p2, k3 free).
// Every image must show the board; throws IntrinsicsError naming the first that does not,
// or that cannot be read, or whose size differs from the first.
IntrinsicsResult CalibrateIntrinsics(const std::vector<std::filesystem::path>& images,
                                     const CalibrationPattern& pattern,
                                     const IntrinsicsProgress& progress = {});
// As above on views already detected (needs at least 3).
IntrinsicsResult CalibrateIntrinsicsFromViews(std::vector<PatternView> views, cv::Size image_size,
                                              const CalibrationPattern& pattern);

// intrinsics.json: schema, width, height, camera_matrix (3×3 as rows), distortion
// [k1, k2, p1, p2, k3], rms_px, the pattern and per-image corner counts and RMS.
nlohmann::json IntrinsicsToJson(const IntrinsicsResult& result);
// Reads an intrinsics.json (e.g. to seed the mirror calibration); ConfigError naming the
// file and key on bad content.
CameraIntrinsics ReadIntrinsicsJson(const std::filesystem::path& file);

// An intrinsics.json as the mirror calibration uses it: the lens, and the board corners it
// was fitted to (where in the image the model rests on data; empty in older files).
struct LensCalibration {
  CameraIntrinsics intrinsics;
  std::vector<Eigen::Vector2d> support_px;
  double rms_px = 0.0;
};
LensCalibration ReadLensJson(const std::filesystem::path& file);

}  // namespace mirrorscan

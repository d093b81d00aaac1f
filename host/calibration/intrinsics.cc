#include "host/calibration/intrinsics.h"

#include <cmath>
#include <cstdio>
#include <utility>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/config/json_reader.h"

namespace mirrorscan {

namespace {

// ChArUco corners a view needs: calibrateCamera needs 4 per planar view; a few more make
// a single view's pose well determined.
constexpr size_t kMinCharucoCorners = 6;
constexpr size_t kMinViews = 3;

const std::vector<std::pair<std::string, cv::aruco::PREDEFINED_DICTIONARY_NAME>>& Dictionaries() {
  namespace aruco = cv::aruco;
  static const std::vector<std::pair<std::string, aruco::PREDEFINED_DICTIONARY_NAME>> names = {
      {"DICT_4X4_50", aruco::DICT_4X4_50},
      {"DICT_4X4_100", aruco::DICT_4X4_100},
      {"DICT_4X4_250", aruco::DICT_4X4_250},
      {"DICT_4X4_1000", aruco::DICT_4X4_1000},
      {"DICT_5X5_50", aruco::DICT_5X5_50},
      {"DICT_5X5_100", aruco::DICT_5X5_100},
      {"DICT_5X5_250", aruco::DICT_5X5_250},
      {"DICT_5X5_1000", aruco::DICT_5X5_1000},
      {"DICT_6X6_50", aruco::DICT_6X6_50},
      {"DICT_6X6_100", aruco::DICT_6X6_100},
      {"DICT_6X6_250", aruco::DICT_6X6_250},
      {"DICT_6X6_1000", aruco::DICT_6X6_1000},
      {"DICT_7X7_50", aruco::DICT_7X7_50},
      {"DICT_7X7_100", aruco::DICT_7X7_100},
      {"DICT_7X7_250", aruco::DICT_7X7_250},
      {"DICT_7X7_1000", aruco::DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", aruco::DICT_ARUCO_ORIGINAL}};
  return names;
}

cv::Ptr<cv::aruco::CharucoBoard> MakeCharucoBoard(const CalibrationPattern& pattern) {
  for (const auto& [name, id] : Dictionaries()) {
    if (name == pattern.dictionary) {
      return cv::aruco::CharucoBoard::create(
          pattern.columns, pattern.rows, static_cast<float>(pattern.square_mm),
          static_cast<float>(pattern.marker_mm), cv::aruco::getPredefinedDictionary(id));
    }
  }
  std::string known;
  for (const auto& entry : Dictionaries()) known += (known.empty() ? "" : ", ") + entry.first;
  throw IntrinsicsError("--dictionary " + pattern.dictionary + ": not one of " + known);
}

cv::Mat ReadGray(const std::filesystem::path& path) {
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw IntrinsicsError(path.string() + ": cannot read the image");
  return image;
}

PatternView DetectChessboard(const cv::Mat& gray, const CalibrationPattern& pattern,
                             const std::string& image_name) {
  const cv::Size size(pattern.columns, pattern.rows);
  PatternView view;
  view.image = image_name;
  // The classic detector first; where it fails (a board at the image's edge against a black
  // background, as a camera looking up sees it) OpenCV's sector-based one.
  if (!cv::findChessboardCorners(gray, size, view.corners_px,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE) &&
      !cv::findChessboardCornersSB(gray, size, view.corners_px, cv::CALIB_CB_EXHAUSTIVE)) {
    throw IntrinsicsError(image_name + ": no " + std::to_string(pattern.columns) + "x" +
                          std::to_string(pattern.rows) + " chessboard found");
  }
  // The window and stopping rule of OpenCV's calibration sample, on the image smoothed
  // first: cornerSubPix fits to gradients, which the sensor's noise dominates; a Gaussian
  // of 1.5 px (small against the squares) took the corners on the virtual cabinet's
  // captures from 0.041 to 0.030 px RMS from the true ones (docs/calibration.md).
  cv::Mat smoothed;
  cv::GaussianBlur(gray, smoothed, cv::Size(0, 0), 1.5);
  cv::cornerSubPix(smoothed, view.corners_px, cv::Size(11, 11), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 1e-4));
  for (int r = 0; r < pattern.rows; ++r) {
    for (int c = 0; c < pattern.columns; ++c) {
      view.corners_on_board_mm.emplace_back(static_cast<float>(c * pattern.square_mm),
                                            static_cast<float>(r * pattern.square_mm), 0.f);
    }
  }
  return view;
}

PatternView DetectCharuco(const cv::Mat& gray, const CalibrationPattern& pattern,
                          const std::string& image_name) {
  const cv::Ptr<cv::aruco::CharucoBoard> board = MakeCharucoBoard(pattern);
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  cv::aruco::detectMarkers(gray, board->dictionary, marker_corners, marker_ids);
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  if (!marker_ids.empty()) {
    cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, board, corners, ids);
  }
  if (corners.size() < kMinCharucoCorners) {
    throw IntrinsicsError(image_name + ": no ChArUco board found (" +
                          std::to_string(marker_ids.size()) + " markers, " +
                          std::to_string(corners.size()) + " corners; need " +
                          std::to_string(kMinCharucoCorners) + ")");
  }
  PatternView view;
  view.image = image_name;
  view.corners_px = std::move(corners);
  for (int id : ids) view.corners_on_board_mm.push_back(board->chessboardCorners.at(id));
  return view;
}

}  // namespace

void CalibrationPattern::Validate() const {
  const char* size_option = kind == Kind::kChessboard ? "--chessboard" : "--charuco";
  const int min_size = kind == Kind::kChessboard ? 2 : 3;
  if (columns < min_size || rows < min_size) {
    throw IntrinsicsError(std::string(size_option) + ": needs at least " +
                          std::to_string(min_size) + " in each direction, got " +
                          std::to_string(columns) + "x" + std::to_string(rows));
  }
  if (!(square_mm > 0) || !std::isfinite(square_mm))
    throw IntrinsicsError("--square: must be a positive length in mm");
  if (kind == Kind::kCharuco) {
    if (!(marker_mm > 0) || !(marker_mm < square_mm))
      throw IntrinsicsError("--marker: must be positive and smaller than --square");
    MakeCharucoBoard(*this);  // checks the dictionary name
  }
}

std::pair<int, int> CalibrationPattern::ParseSize(const std::string& text,
                                                  const std::string& option) {
  int columns = 0, rows = 0;
  char rest = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &columns, &rows, &rest) != 2 || columns <= 0 ||
      rows <= 0) {
    throw IntrinsicsError(option + " " + text + ": expected COLUMNSxROWS, e.g. 9x6");
  }
  return {columns, rows};
}

PatternView DetectPattern(const cv::Mat& gray, const CalibrationPattern& pattern,
                          const std::string& image_name) {
  return pattern.kind == CalibrationPattern::Kind::kChessboard
             ? DetectChessboard(gray, pattern, image_name)
             : DetectCharuco(gray, pattern, image_name);
}

IntrinsicsResult CalibrateIntrinsicsFromViews(std::vector<PatternView> views, cv::Size image_size,
                                              const CalibrationPattern& pattern) {
  if (views.size() < kMinViews) {
    throw IntrinsicsError("need at least " + std::to_string(kMinViews) +
                          " images showing the board, got " + std::to_string(views.size()));
  }
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (const PatternView& v : views) {
    object_points.push_back(v.corners_on_board_mm);
    image_points.push_back(v.corners_px);
  }
  cv::Mat camera_matrix, distortion;
  std::vector<cv::Mat> rvecs, tvecs;
  IntrinsicsResult result;
  result.rms_px = cv::calibrateCamera(object_points, image_points, image_size, camera_matrix,
                                      distortion, rvecs, tvecs);
  result.image_size = image_size;
  result.pattern = pattern;
  CameraIntrinsics& k = result.intrinsics;
  k.width = image_size.width;
  k.height = image_size.height;
  k.fx = camera_matrix.at<double>(0, 0);
  k.fy = camera_matrix.at<double>(1, 1);
  k.cx = camera_matrix.at<double>(0, 2);
  k.cy = camera_matrix.at<double>(1, 2);
  const cv::Mat d = distortion.reshape(1, 1);
  k.k1 = d.at<double>(0);
  k.k2 = d.at<double>(1);
  k.p1 = d.at<double>(2);
  k.p2 = d.at<double>(3);
  k.k3 = d.at<double>(4);
  for (size_t i = 0; i < views.size(); ++i) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object_points[i], rvecs[i], tvecs[i], camera_matrix, distortion, projected);
    views[i].rms_px = cv::norm(projected, image_points[i], cv::NORM_L2) /
                      std::sqrt(static_cast<double>(projected.size()));
  }
  result.views = std::move(views);
  return result;
}

IntrinsicsResult CalibrateIntrinsics(const std::vector<std::filesystem::path>& images,
                                     const CalibrationPattern& pattern,
                                     const IntrinsicsProgress& progress) {
  pattern.Validate();
  std::vector<PatternView> views;
  cv::Size image_size;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string name = images[i].string();
    const cv::Mat gray = ReadGray(images[i]);
    if (i == 0) image_size = gray.size();
    if (gray.size() != image_size) {
      throw IntrinsicsError(name + ": image is " + std::to_string(gray.cols) + "x" +
                            std::to_string(gray.rows) + ", the first was " +
                            std::to_string(image_size.width) + "x" +
                            std::to_string(image_size.height));
    }
    views.push_back(DetectPattern(gray, pattern, name));
    if (progress) progress(i + 1, images.size(), name);
  }
  return CalibrateIntrinsicsFromViews(std::move(views), image_size, pattern);
}

nlohmann::json IntrinsicsToJson(const IntrinsicsResult& result) {
  const CameraIntrinsics& k = result.intrinsics;
  const CalibrationPattern& p = result.pattern;
  nlohmann::json pattern = {
      {"type", p.kind == CalibrationPattern::Kind::kChessboard ? "chessboard" : "charuco"},
      {"columns", p.columns},
      {"rows", p.rows},
      {"square_mm", p.square_mm}};
  if (p.kind == CalibrationPattern::Kind::kCharuco) {
    pattern["marker_mm"] = p.marker_mm;
    pattern["dictionary"] = p.dictionary;
  }
  nlohmann::json images = nlohmann::json::array();
  for (const PatternView& v : result.views) {
    // The corners show where in the image the lens model rests on data (calibrate's
    // coverage check); 0.01 px is far below their noise.
    nlohmann::json corners = nlohmann::json::array();
    for (const cv::Point2f& c : v.corners_px) {
      corners.push_back({std::round(c.x * 100.0) / 100.0, std::round(c.y * 100.0) / 100.0});
    }
    images.push_back({{"path", v.image},
                      {"corners", v.corners_px.size()},
                      {"rms_px", v.rms_px},
                      {"corners_px", corners}});
  }
  return {{"schema", "mirrorscan.intrinsics"},
          {"version", 1},
          {"width", k.width},
          {"height", k.height},
          {"camera_matrix", {{k.fx, 0.0, k.cx}, {0.0, k.fy, k.cy}, {0.0, 0.0, 1.0}}},
          {"distortion", {k.k1, k.k2, k.p1, k.p2, k.k3}},
          {"rms_px", result.rms_px},
          {"pattern", pattern},
          {"images", images}};
}

CameraIntrinsics ReadIntrinsicsJson(const std::filesystem::path& file) {
  return ReadLensJson(file).intrinsics;
}

LensCalibration ReadLensJson(const std::filesystem::path& file) {
  const nlohmann::json json = JsonReader::ParseFile(file);
  const JsonReader reader(json, file.string());
  if (reader.String("schema") != "mirrorscan.intrinsics")
    reader.Fail("schema", "expected \"mirrorscan.intrinsics\"");
  if (reader.Integer("version") != 1) reader.Fail("version", "only version 1 is known");
  CameraIntrinsics k;
  k.width = reader.Integer("width", std::nullopt, 1);
  k.height = reader.Integer("height", std::nullopt, 1);
  const nlohmann::json* matrix =
      json.is_object() && json.contains("camera_matrix") ? &json["camera_matrix"] : nullptr;
  if (!matrix) reader.Fail("camera_matrix", "missing");
  std::vector<double> r0, r1, r2;
  for (int r = 0; r < 3; ++r) {
    std::vector<double>& row = r == 0 ? r0 : r == 1 ? r1 : r2;
    const bool row_ok = matrix->is_array() && matrix->size() == 3 && (*matrix)[r].is_array() &&
                        (*matrix)[r].size() == 3;
    for (int c = 0; row_ok && c < 3; ++c)
      if ((*matrix)[r][c].is_number()) row.push_back((*matrix)[r][c].get<double>());
    if (row.size() != 3) reader.Fail("camera_matrix", "must be 3 rows of 3 numbers");
  }
  if (r0[1] != 0 || r1[0] != 0 || r2[0] != 0 || r2[1] != 0 || r2[2] != 1)
    reader.Fail("camera_matrix", "must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]");
  if (!(r0[0] > 0) || !(r1[1] > 0)) reader.Fail("camera_matrix", "fx and fy must be positive");
  k.fx = r0[0];
  k.cx = r0[2];
  k.fy = r1[1];
  k.cy = r1[2];
  const std::vector<double> d = reader.Numbers("distortion", 5);
  k.k1 = d[0];
  k.k2 = d[1];
  k.p1 = d[2];
  k.p2 = d[3];
  k.k3 = d[4];
  LensCalibration lens;
  lens.intrinsics = k;
  lens.rms_px = reader.Number("rms_px", 0.0, 0.0, 1e6);
  if (reader.Has("images")) {
    for (const JsonReader& image : reader.Objects("images")) {
      if (!image.Has("corners_px")) continue;
      const nlohmann::json& corners = image.value()["corners_px"];
      if (!corners.is_array()) image.Fail("corners_px", "expected an array of [u, v]");
      for (const nlohmann::json& c : corners) {
        if (!c.is_array() || c.size() != 2 || !c[0].is_number() || !c[1].is_number()) {
          image.Fail("corners_px", "expected an array of [u, v]");
        }
        const Eigen::Vector2d pixel(c[0].get<double>(), c[1].get<double>());
        if (!(pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() <= k.width - 0.5 &&
              pixel.y() <= k.height - 0.5)) {
          image.Fail("corners_px", "a corner lies outside the image");
        }
        lens.support_px.push_back(pixel);
      }
    }
  }
  return lens;
}

}  // namespace mirrorscan

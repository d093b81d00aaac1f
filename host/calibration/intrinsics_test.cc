#include "host/calibration/intrinsics.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/config/json_reader.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;

// OpenCV's own sample photographs of a 9x6 chessboard (Debian's opencv-doc, installed by
// scripts/setup). left10.jpg does not exist.
std::vector<fs::path> OpenCvSampleImages() {
  const fs::path dir = "/usr/share/doc/opencv-doc/examples/data";
  std::vector<fs::path> images;
  for (int i = 1; i <= 14; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "left%02d.jpg", i);
    if (fs::exists(dir / name)) images.push_back(dir / name);
  }
  return images;
}

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mirrorscan_intrinsics_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The truth for real photographs: the intrinsics OpenCV ships beside its sample images
// (left_intrinsics.yml, made by its calibration sample with a fixed aspect ratio:
// fx = fy = 535.9, cx 342.3, cy 235.6, RMS 0.39 px). The known-lens tests below hold the
// figures to a camera the images were made with.
TEST(CalibrateIntrinsics, OpenCvSamplesGiveTheIntrinsicsOpenCvShipsWithThem) {
  const std::vector<fs::path> images = OpenCvSampleImages();
  ASSERT_EQ(images.size(), 13u) << "install opencv-doc (scripts/setup)";
  CalibrationPattern pattern;  // 9x6
  pattern.square_mm = 25.0;
  size_t progress_calls = 0;
  const IntrinsicsResult result =
      CalibrateIntrinsics(images, pattern, [&](size_t done, size_t total, const std::string&) {
        ++progress_calls;
        EXPECT_EQ(total, images.size());
        EXPECT_EQ(done, progress_calls);
      });
  EXPECT_EQ(progress_calls, images.size());

  const CameraIntrinsics& got = result.intrinsics;
  EXPECT_EQ(result.image_size, cv::Size(640, 480));
  EXPECT_NEAR(got.fx, 535.9, 0.01 * 535.9);
  EXPECT_NEAR(got.fy, 535.9, 0.01 * 535.9);
  EXPECT_NEAR(got.cx, 342.3, 3.0);
  EXPECT_NEAR(got.cy, 235.6, 3.0);
  EXPECT_NEAR(got.k1, -0.266, 0.03);
  // The corners refined on the smoothed image fit better than that sample's (0.25 px).
  EXPECT_LT(result.rms_px, 0.3);
  ASSERT_EQ(result.views.size(), images.size());
  for (const PatternView& v : result.views) {
    EXPECT_EQ(v.corners_px.size(), 54u);
    EXPECT_LT(v.rms_px, 1.5);  // left02.jpg: 1.18 px in OpenCV's own run
  }
}

// A board picture (white margin, black/white squares; ChArUco markers from OpenCV) seen by
// a known camera with distortion: each output pixel is undistorted, taken through the
// board's pose to the board plane and sampled from the picture.
struct BoardPicture {
  cv::Mat image;          // blurred slightly so sampling it does not alias
  double px_per_mm;       // picture scale
  cv::Point2d origin_px;  // where board point (0, 0) lies in the picture
};

cv::Mat ViewBoard(const BoardPicture& board, const cv::Matx33d& k, const cv::Mat& distortion,
                  const cv::Vec3d& rvec, const cv::Vec3d& tvec, cv::Size size) {
  std::vector<cv::Point2f> pixels;
  for (int v = 0; v < size.height; ++v)
    for (int u = 0; u < size.width; ++u) pixels.emplace_back(u, v);
  std::vector<cv::Point2f> normalised;
  cv::undistortPoints(pixels, normalised, k, distortion, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-9));
  cv::Matx33d r;
  cv::Rodrigues(rvec, r);
  // Board plane z = 0 to normalised image: [r1 r2 t]; its inverse maps back.
  const cv::Matx33d cam_from_board(r(0, 0), r(0, 1), tvec[0], r(1, 0), r(1, 1), tvec[1], r(2, 0),
                                   r(2, 1), tvec[2]);
  const cv::Matx33d board_from_cam = cam_from_board.inv();
  cv::Mat map_x(size, CV_32F), map_y(size, CV_32F);
  for (size_t i = 0; i < pixels.size(); ++i) {
    const cv::Vec3d b = board_from_cam * cv::Vec3d(normalised[i].x, normalised[i].y, 1.0);
    const int u = static_cast<int>(pixels[i].x), v = static_cast<int>(pixels[i].y);
    map_x.at<float>(v, u) = static_cast<float>(board.origin_px.x + b[0] / b[2] * board.px_per_mm);
    map_y.at<float>(v, u) = static_cast<float>(board.origin_px.y + b[1] / b[2] * board.px_per_mm);
  }
  cv::Mat out;
  cv::remap(board.image, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(200));
  return out;
}

struct TrueCamera {
  cv::Size size{800, 600};
  cv::Matx33d k{900, 0, 404.5, 0, 905, 296.0, 0, 0, 1};
  cv::Mat distortion = (cv::Mat_<double>(1, 5) << -0.12, 0.08, 4e-4, -3e-4, 0.0);
};

// Views of a board whose centre is `center_mm` (board frame), tilted up to ±30°.
std::vector<cv::Mat> ViewsOf(const BoardPicture& board, const TrueCamera& camera,
                             cv::Point2d center_mm, double distance_mm) {
  const std::vector<cv::Vec3d> tilts_deg = {{0, 0, 0},     {25, 0, 5},    {-25, 0, -5},
                                            {0, 28, 10},   {0, -28, -10}, {18, 18, 90},
                                            {-18, 20, 30}, {20, -18, -30}};
  std::vector<cv::Mat> views;
  for (const cv::Vec3d& t : tilts_deg) {
    const double deg = CV_PI / 180;
    cv::Matx33d rx, ry, rz;
    cv::Rodrigues(cv::Vec3d(t[0] * deg, 0, 0), rx);
    cv::Rodrigues(cv::Vec3d(0, t[1] * deg, 0), ry);
    cv::Rodrigues(cv::Vec3d(0, 0, t[2] * deg), rz);
    const cv::Matx33d r = rx * ry * rz;
    cv::Vec3d rvec;
    cv::Rodrigues(r, rvec);
    const cv::Vec3d tvec =
        cv::Vec3d(0, 0, distance_mm) - r * cv::Vec3d(center_mm.x, center_mm.y, 0);
    views.push_back(ViewBoard(board, camera.k, camera.distortion, rvec, tvec, camera.size));
  }
  return views;
}

void ExpectRecovered(const IntrinsicsResult& result, const TrueCamera& truth) {
  const CameraIntrinsics& got = result.intrinsics;
  EXPECT_NEAR(got.fx, truth.k(0, 0), 0.001 * truth.k(0, 0));
  EXPECT_NEAR(got.fy, truth.k(1, 1), 0.001 * truth.k(1, 1));
  EXPECT_NEAR(got.cx, truth.k(0, 2), 1.0);
  EXPECT_NEAR(got.cy, truth.k(1, 2), 1.0);
  EXPECT_NEAR(got.k1, truth.distortion.at<double>(0), 0.01);
  EXPECT_LT(result.rms_px, 0.1);
  // Distortion as a whole: where the recovered model puts points near the field's corners
  // (measured: 0.3 px for the chessboard, 1.2 px for the ChArUco board, whose corners
  // reach less far out).
  for (const cv::Point2d corner : {cv::Point2d(0.4, 0.3), cv::Point2d(-0.4, -0.3)}) {
    std::vector<cv::Point3d> point = {{corner.x, corner.y, 1.0}};
    std::vector<cv::Point2d> want, have;
    cv::projectPoints(point, cv::Vec3d(), cv::Vec3d(), truth.k, truth.distortion, want);
    const cv::Matx33d k_got(got.fx, 0, got.cx, 0, got.fy, got.cy, 0, 0, 1);
    const std::vector<double> d_got = {got.k1, got.k2, got.p1, got.p2, got.k3};
    cv::projectPoints(point, cv::Vec3d(), cv::Vec3d(), k_got, d_got, have);
    EXPECT_LT(cv::norm(want[0] - have[0]), 1.5) << corner;
  }
}

TEST(CalibrateIntrinsics, RecoversKnownCameraFromChessboardViews) {
  CalibrationPattern pattern;
  pattern.columns = 9;
  pattern.rows = 6;
  pattern.square_mm = 30.0;
  // 10 × 7 squares of 60 picture pixels in a margin of one square.
  constexpr int kSquarePx = 60;
  BoardPicture board;
  board.image = cv::Mat((pattern.rows + 3) * kSquarePx, (pattern.columns + 3) * kSquarePx, CV_8U,
                        cv::Scalar(230));
  for (int r = 0; r <= pattern.rows; ++r)
    for (int c = 0; c <= pattern.columns; ++c)
      if ((r + c) % 2 == 0)
        board.image(cv::Rect((c + 1) * kSquarePx, (r + 1) * kSquarePx, kSquarePx, kSquarePx)) = 25;
  cv::GaussianBlur(board.image, board.image, cv::Size(0, 0), 1.0);
  board.px_per_mm = kSquarePx / pattern.square_mm;
  // Picture pixel centres are integers, so a square's edge lies at index - 0.5.
  board.origin_px = {2 * kSquarePx - 0.5, 2 * kSquarePx - 0.5};

  const TrueCamera camera;
  const std::vector<cv::Mat> views =
      ViewsOf(board, camera, {4 * pattern.square_mm, 2.5 * pattern.square_mm}, 500.0);
  std::vector<PatternView> detected;
  for (size_t i = 0; i < views.size(); ++i)
    detected.push_back(DetectPattern(views[i], pattern, "view" + std::to_string(i)));
  ExpectRecovered(CalibrateIntrinsicsFromViews(detected, camera.size, pattern), camera);
}

TEST(CalibrateIntrinsics, RecoversKnownCameraFromCharucoViews) {
  CalibrationPattern pattern;
  pattern.kind = CalibrationPattern::Kind::kCharuco;
  pattern.columns = 11;
  pattern.rows = 8;
  pattern.square_mm = 30.0;
  pattern.marker_mm = 22.0;
  const auto charuco =
      cv::aruco::CharucoBoard::create(pattern.columns, pattern.rows, 30.f, 22.f,
                                      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50));
  constexpr int kSquarePx = 60, kMarginPx = 60;
  BoardPicture board;
  charuco->draw(cv::Size(pattern.columns * kSquarePx + 2 * kMarginPx,
                         pattern.rows * kSquarePx + 2 * kMarginPx),
                board.image, kMarginPx);
  cv::GaussianBlur(board.image, board.image, cv::Size(0, 0), 1.0);
  board.px_per_mm = kSquarePx / pattern.square_mm;
  board.origin_px = {kMarginPx - 0.5, kMarginPx - 0.5};

  const TrueCamera camera;
  const std::vector<cv::Mat> views =
      ViewsOf(board, camera, {pattern.columns * 15.0, pattern.rows * 15.0}, 430.0);
  std::vector<PatternView> detected;
  for (size_t i = 0; i < views.size(); ++i) {
    detected.push_back(DetectPattern(views[i], pattern, "view" + std::to_string(i)));
    EXPECT_GE(detected.back().corners_px.size(), 25u) << i;
  }
  ExpectRecovered(CalibrateIntrinsicsFromViews(detected, camera.size, pattern), camera);
}

TEST(CalibrateIntrinsics, ImageWithoutBoardIsAnErrorNamingIt) {
  const std::vector<fs::path> samples = OpenCvSampleImages();
  ASSERT_GE(samples.size(), 3u);
  const fs::path dir = TempDir("noboard");
  const fs::path blank = dir / "blank.png";
  cv::imwrite(blank.string(), cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
  CalibrationPattern pattern;
  try {
    CalibrateIntrinsics({samples[0], blank, samples[1], samples[2]}, pattern);
    FAIL() << "no error";
  } catch (const IntrinsicsError& e) {
    EXPECT_EQ(std::string(e.what()), blank.string() + ": no 9x6 chessboard found");
  }
  pattern.kind = CalibrationPattern::Kind::kCharuco;
  pattern.columns = 5;
  pattern.rows = 7;
  pattern.marker_mm = 15.0;
  try {
    CalibrateIntrinsics({blank}, pattern);
    FAIL() << "no error";
  } catch (const IntrinsicsError& e) {
    EXPECT_NE(std::string(e.what()).find(blank.string() + ": no ChArUco board found"),
              std::string::npos)
        << e.what();
  }
}

TEST(CalibrateIntrinsics, BadInputsAreOneClearError) {
  const std::vector<fs::path> samples = OpenCvSampleImages();
  ASSERT_GE(samples.size(), 3u);
  const fs::path dir = TempDir("bad");
  const fs::path not_image = dir / "notes.jpg";
  std::ofstream(not_image) << "not a picture";
  const fs::path small = dir / "small.png";
  cv::Mat half;
  cv::resize(cv::imread(samples[1].string()), half, cv::Size(320, 240));
  cv::imwrite(small.string(), half);
  const CalibrationPattern pattern;
  auto message = [&](const std::vector<fs::path>& images) {
    try {
      CalibrateIntrinsics(images, pattern);
    } catch (const IntrinsicsError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message({samples[0], not_image}), not_image.string() + ": cannot read the image");
  EXPECT_EQ(message({dir / "missing.png"}),
            (dir / "missing.png").string() + ": cannot read the image");
  EXPECT_EQ(message({samples[0], small}),
            small.string() + ": image is 320x240, the first was 640x480");
  EXPECT_EQ(message({samples[0], samples[1]}), "need at least 3 images showing the board, got 2");

  EXPECT_THROW(CalibrationPattern::ParseSize("9by6", "--chessboard"), IntrinsicsError);
  EXPECT_EQ(CalibrationPattern::ParseSize("9x6", "--chessboard"), std::make_pair(9, 6));
  CalibrationPattern bad;
  bad.square_mm = 0;
  EXPECT_THROW(bad.Validate(), IntrinsicsError);
  bad = CalibrationPattern();
  bad.kind = CalibrationPattern::Kind::kCharuco;
  bad.marker_mm = 10;
  bad.dictionary = "DICT_9X9_1";
  try {
    bad.Validate();
    FAIL();
  } catch (const IntrinsicsError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("--dictionary DICT_9X9_1: not one of DICT_4X4_50", 0), 0u)
        << e.what();
  }
}

TEST(IntrinsicsJson, RoundTripsAndNamesBadKeys) {
  const std::vector<fs::path> samples = OpenCvSampleImages();
  ASSERT_GE(samples.size(), 3u);
  const IntrinsicsResult result =
      CalibrateIntrinsics({samples.begin(), samples.begin() + 5}, CalibrationPattern());
  const nlohmann::json json = IntrinsicsToJson(result);
  EXPECT_EQ(json["camera_matrix"].size(), 3u);
  EXPECT_DOUBLE_EQ(json["camera_matrix"][0][0].get<double>(), result.intrinsics.fx);
  EXPECT_DOUBLE_EQ(json["camera_matrix"][1][2].get<double>(), result.intrinsics.cy);
  EXPECT_DOUBLE_EQ(json["rms_px"].get<double>(), result.rms_px);
  EXPECT_EQ(json["images"].size(), 5u);

  const fs::path dir = TempDir("json");
  const fs::path file = dir / "intrinsics.json";
  std::ofstream(file) << json.dump(2);
  const CameraIntrinsics read = ReadIntrinsicsJson(file);
  EXPECT_EQ(read.width, 640);
  EXPECT_DOUBLE_EQ(read.fx, result.intrinsics.fx);
  EXPECT_DOUBLE_EQ(read.k3, result.intrinsics.k3);

  nlohmann::json broken = json;
  broken["camera_matrix"][2] = {0, 0};
  std::ofstream(file) << broken.dump(2);
  try {
    ReadIntrinsicsJson(file);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              file.string() + ": camera_matrix: must be 3 rows of 3 numbers");
  }
  broken = json;
  broken.erase("distortion");
  std::ofstream(file) << broken.dump(2);
  EXPECT_THROW(ReadIntrinsicsJson(file), ConfigError);
}

}  // namespace
}  // namespace mirrorscan

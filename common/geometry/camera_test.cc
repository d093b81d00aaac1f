#include "common/geometry/camera.h"

#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

namespace mirrorscan {
namespace {

CameraIntrinsics TestIntrinsics() {
  CameraIntrinsics k;
  k.fx = 1210.5;
  k.fy = 1207.25;
  k.cx = 515.3;
  k.cy = 380.9;
  k.k1 = -0.21;
  k.k2 = 0.12;
  k.p1 = 0.0011;
  k.p2 = -0.0007;
  k.k3 = -0.03;
  return k;
}

cv::Mat CameraMatrix(const CameraIntrinsics& k) {
  return (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
}
cv::Mat DistCoeffs(const CameraIntrinsics& k) {
  return (cv::Mat_<double>(1, 5) << k.k1, k.k2, k.p1, k.p2, k.k3);
}

TEST(CameraTest, ProjectMatchesOpenCvProjectPoints) {
  const CameraIntrinsics k = TestIntrinsics();
  Camera camera{k, LookAt({300, -2000, 1500}, {0, 0, 1000})};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-500, 500), z(0, 2000);
  std::vector<cv::Point3d> points;
  for (int i = 0; i < 500; ++i) points.emplace_back(xy(rng), xy(rng), z(rng));

  const Eigen::Matrix3d r = camera.cam_from_world.RotationMatrix();
  cv::Mat r_cv(3, 3, CV_64F), rvec;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r_cv.at<double>(i, j) = r(i, j);
  cv::Rodrigues(r_cv, rvec);
  const Eigen::Vector3d t = camera.cam_from_world.translation;
  cv::Mat tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, rvec, tvec, CameraMatrix(k), DistCoeffs(k), expected);

  for (size_t i = 0; i < points.size(); ++i) {
    const auto pixel = camera.ProjectWorld({points[i].x, points[i].y, points[i].z});
    ASSERT_TRUE(pixel);
    EXPECT_NEAR(pixel->x(), expected[i].x, 1e-6);
    EXPECT_NEAR(pixel->y(), expected[i].y, 1e-6);
  }
}

TEST(CameraTest, UnprojectMatchesOpenCvUndistortPoints) {
  const CameraIntrinsics k = TestIntrinsics();
  std::vector<cv::Point2d> pixels;
  for (int v = 0; v < k.height; v += 37)
    for (int u = 0; u < k.width; u += 41) pixels.emplace_back(u + 0.25, v - 0.125);
  std::vector<cv::Point2d> expected;
  // OpenCV iterates a fixed number of times unless told to converge tightly.
  cv::undistortPoints(
      pixels, expected, CameraMatrix(k), DistCoeffs(k), cv::noArray(), cv::noArray(),
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-15));
  for (size_t i = 0; i < pixels.size(); ++i) {
    const auto ray = k.Unproject({pixels[i].x, pixels[i].y});
    ASSERT_TRUE(ray);
    // Compare in pixel units: normalised coordinates scaled by the focal length.
    EXPECT_NEAR(ray->x() / ray->z() * k.fx, expected[i].x * k.fx, 1e-6) << i;
    EXPECT_NEAR(ray->y() / ray->z() * k.fy, expected[i].y * k.fy, 1e-6) << i;
  }
}

TEST(CameraTest, UnprojectInvertsProject) {
  const CameraIntrinsics k = TestIntrinsics();
  for (int v = 0; v < k.height; v += 20) {
    for (int u = 0; u < k.width; u += 20) {
      const Eigen::Vector2d pixel(u + 0.3, v + 0.7);
      const auto ray = k.Unproject(pixel);
      ASSERT_TRUE(ray);
      const auto back = k.Project(*ray * 1234.0);
      ASSERT_TRUE(back);
      EXPECT_LT((*back - pixel).norm(), 1e-9);
    }
  }
}

TEST(CameraTest, RayThroughPixelHitsProjectedPoint) {
  Camera camera{TestIntrinsics(), LookAt({-200, -2500, 900}, {0, 0, 1100})};
  const Eigen::Vector3d point(120, 80, 1300);
  const auto pixel = camera.ProjectWorld(point);
  ASSERT_TRUE(pixel);
  const auto ray = camera.RayThroughPixel(*pixel);
  ASSERT_TRUE(ray);
  const Eigen::Vector3d to_point = point - ray->origin;
  EXPECT_LT((to_point - to_point.dot(ray->direction) * ray->direction).norm(), 1e-8);
}

TEST(CameraTest, PointBehindCameraDoesNotProject) {
  CameraIntrinsics k;
  EXPECT_FALSE(k.Project({0, 0, -1}));
  EXPECT_FALSE(k.Project({0, 0, 0}));
}

TEST(CameraTest, LookAtPutsTargetOnOpticalAxisWithZUpAsImageUp) {
  const Rigid3d cam_from_world = LookAt({0, -3000, 1000}, {0, 0, 1000});
  const Eigen::Vector3d target = cam_from_world * Eigen::Vector3d(0, 0, 1000);
  EXPECT_NEAR(target.x(), 0, 1e-9);
  EXPECT_NEAR(target.y(), 0, 1e-9);
  EXPECT_NEAR(target.z(), 3000, 1e-9);
  // A point above the target appears higher in the image (smaller v, camera y down).
  EXPECT_LT((cam_from_world * Eigen::Vector3d(0, 0, 1500)).y(), 0);
  // World +x appears to the right (camera +x).
  EXPECT_GT((cam_from_world * Eigen::Vector3d(500, 0, 1000)).x(), 0);
}

}  // namespace
}  // namespace mirrorscan

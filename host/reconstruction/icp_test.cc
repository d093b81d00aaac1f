#include "host/reconstruction/icp.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {
namespace {

// ICP on an analytic ellipsoid seen as two overlapping views, one moved 1.5 mm: the
// correction brings it back onto the surface.
TEST(Icp, IcpTakesBackAViewMovedOffTheOthers) {
  const Eigen::Vector3d radii(150, 110, 300);
  auto on_surface = [&](double azimuth, double elevation) {
    return Eigen::Vector3d(radii.x() * std::cos(elevation) * std::cos(azimuth),
                           radii.y() * std::cos(elevation) * std::sin(azimuth),
                           1200 + radii.z() * std::sin(elevation));
  };
  auto distance = [&](const Eigen::Vector3f& p) {  // to the ellipsoid, first order
    const Eigen::Vector3d q = p.cast<double>() - Eigen::Vector3d(0, 0, 1200);
    const double f = (q.array() / radii.array()).matrix().norm();
    const Eigen::Vector3d gradient = (q.array() / radii.array().square()).matrix();
    return std::abs(f - 1) * f / gradient.norm();
  };
  PointCloud cloud;
  for (double azimuth = -M_PI; azimuth < M_PI; azimuth += 0.01) {
    for (double elevation = -1.2; elevation < 1.2; elevation += 0.01) {
      CloudPoint p;
      const Eigen::Vector3d q = on_surface(azimuth, elevation);
      p.point_in_world = q.cast<float>();
      const Eigen::Vector3d n =
          ((q - Eigen::Vector3d(0, 0, 1200)).array() / radii.array().square()).matrix();
      p.normal = n.normalized().cast<float>();
      // Front half directly, the back and right side through the right mirror, overlapping.
      const double degrees = azimuth * 180 / M_PI;
      if (degrees < 20) {
        p.view = PointView::kCenter;
        cloud.points.push_back(p);
      }
      if (degrees > -40) {
        p.view = PointView::kRight;
        p.point_in_world += Eigen::Vector3f(0.9f, 1.2f, 0);
        cloud.points.push_back(p);
      }
    }
  }
  auto rms = [&](PointView view) {
    double sum = 0;
    size_t n = 0;
    for (const CloudPoint& p : cloud.points) {
      if (p.view != view) continue;
      sum += std::pow(distance(p.point_in_world), 2);
      ++n;
    }
    return std::sqrt(sum / n);
  };
  const double moved = rms(PointView::kRight);
  const IcpSummary icp = RefineViews(&cloud);
  ASSERT_TRUE(icp.ran);
  const auto step = std::find_if(icp.steps.begin(), icp.steps.end(), [](const auto& s) {
    return s.what == "camera 0 right against the views before it";
  });
  ASSERT_NE(step, icp.steps.end());
  std::printf("moved view: %.3f mm rms from the surface, %.3f after ICP (%.3f mm, %.4f deg)\n",
              moved, rms(PointView::kRight), step->translation_mm, step->rotation_deg);
  EXPECT_TRUE(step->applied);
  EXPECT_NEAR(step->translation_mm, 1.5, 0.2);
  EXPECT_LT(rms(PointView::kRight), 0.1);
  EXPECT_LT(rms(PointView::kCenter), 0.1);
}

}  // namespace
}  // namespace mirrorscan::reconstruction

#include "common/geometry/camera.h"

#include <cmath>

namespace mirrorscan {

Eigen::Matrix3d CameraIntrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

Eigen::Vector2d CameraIntrinsics::Distort(const Eigen::Vector2d& p) const {
  const double x = p.x(), y = p.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

namespace {

// Distort's Jacobian at a normalised point.
Eigen::Matrix2d DistortJacobian(const CameraIntrinsics& c, const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  const double radial_r2 = c.k1 + r2 * (2.0 * c.k2 + 3.0 * r2 * c.k3);  // d radial / d r2
  const double cross = 2.0 * x * y * radial_r2 + 2.0 * c.p1 * x + 2.0 * c.p2 * y;
  Eigen::Matrix2d j;
  j << radial + 2.0 * x * x * radial_r2 + 2.0 * c.p1 * y + 6.0 * c.p2 * x, cross, cross,
      radial + 2.0 * y * y * radial_r2 + 6.0 * c.p1 * y + 2.0 * c.p2 * x;
  return j;
}

}  // namespace

std::optional<Eigen::Vector2d> CameraIntrinsics::Undistort(const Eigen::Vector2d& distorted) const {
  if (!HasDistortion()) return distorted;
  // A few fixed-point steps x = (x_d - tangential(x)) / radial(x) (cv::undistortPoints'
  // iteration), then Newton on Distort(x) = x_d to machine precision; far out, where that
  // has not converged, the fixed point run to convergence first.
  auto solve = [&](int fixed_point_steps) -> std::optional<Eigen::Vector2d> {
    Eigen::Vector2d x = distorted;
    for (int i = 0; i < fixed_point_steps; ++i) {
      const double r2 = x.squaredNorm();
      const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      const double dx = 2.0 * p1 * x.x() * x.y() + p2 * (r2 + 2.0 * x.x() * x.x());
      const double dy = p1 * (r2 + 2.0 * x.y() * x.y()) + 2.0 * p2 * x.x() * x.y();
      if (!(std::abs(radial) > 1e-9)) return std::nullopt;
      x = Eigen::Vector2d((distorted.x() - dx) / radial, (distorted.y() - dy) / radial);
    }
    for (int i = 0; i < 10; ++i) {
      const Eigen::Vector2d residual = Distort(x) - distorted;
      if (residual.squaredNorm() < 1e-30) break;
      const Eigen::Matrix2d jacobian = DistortJacobian(*this, x);
      if (!(std::abs(jacobian.determinant()) > 1e-12)) return std::nullopt;
      x -= jacobian.inverse() * residual;
    }
    if (!x.allFinite() || (Distort(x) - distorted).norm() > 1e-10) return std::nullopt;
    return x;
  };
  if (auto x = solve(3)) return x;
  return solve(20);
}

std::optional<Eigen::Vector2d> CameraIntrinsics::Project(
    const Eigen::Vector3d& point_in_cam) const {
  if (!(point_in_cam.z() > 1e-12)) return std::nullopt;
  const Eigen::Vector2d distorted = Distort(point_in_cam.head<2>() / point_in_cam.z());
  return Eigen::Vector2d(fx * distorted.x() + cx, fy * distorted.y() + cy);
}

std::optional<Eigen::Vector3d> CameraIntrinsics::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  const auto undistorted = Undistort(distorted);
  if (!undistorted) return std::nullopt;
  return Eigen::Vector3d(undistorted->x(), undistorted->y(), 1.0).normalized();
}

std::optional<Ray3d> Camera::RayThroughPixel(const Eigen::Vector2d& pixel) const {
  return RaysThroughPixels().Through(pixel);
}

CameraRays Camera::RaysThroughPixels() const {
  return {intrinsics, cam_from_world.rotation.conjugate().toRotationMatrix(), CenterInWorld()};
}

std::optional<Ray3d> CameraRays::Through(const Eigen::Vector2d& pixel) const {
  const auto direction_in_cam = intrinsics.Unproject(pixel);
  if (!direction_in_cam) return std::nullopt;
  return Ray3d{center_in_world, world_from_cam_rotation * *direction_in_cam};
}

}  // namespace mirrorscan

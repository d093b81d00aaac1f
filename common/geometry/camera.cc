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

std::optional<Eigen::Vector2d> CameraIntrinsics::Undistort(const Eigen::Vector2d& distorted) const {
  if (!HasDistortion()) return distorted;
  // Fixed-point iteration x = (x_d - tangential(x)) / radial(x), then a few Newton steps
  // on Distort(x) = x_d to reach machine precision.
  Eigen::Vector2d x = distorted;
  for (int i = 0; i < 20; ++i) {
    const double r2 = x.squaredNorm();
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dx = 2.0 * p1 * x.x() * x.y() + p2 * (r2 + 2.0 * x.x() * x.x());
    const double dy = p1 * (r2 + 2.0 * x.y() * x.y()) + 2.0 * p2 * x.x() * x.y();
    if (!(std::abs(radial) > 1e-9)) return std::nullopt;
    x = Eigen::Vector2d((distorted.x() - dx) / radial, (distorted.y() - dy) / radial);
  }
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector2d residual = Distort(x) - distorted;
    if (residual.norm() < 1e-15) break;
    constexpr double kStep = 1e-7;
    Eigen::Matrix2d jacobian;
    jacobian.col(0) =
        (Distort(x + Eigen::Vector2d(kStep, 0)) - Distort(x - Eigen::Vector2d(kStep, 0))) /
        (2 * kStep);
    jacobian.col(1) =
        (Distort(x + Eigen::Vector2d(0, kStep)) - Distort(x - Eigen::Vector2d(0, kStep))) /
        (2 * kStep);
    x -= jacobian.inverse() * residual;
  }
  if ((Distort(x) - distorted).norm() > 1e-10 || !x.allFinite()) return std::nullopt;
  return x;
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
  const auto direction_in_cam = intrinsics.Unproject(pixel);
  if (!direction_in_cam) return std::nullopt;
  const Eigen::Quaterniond world_from_cam = cam_from_world.rotation.conjugate();
  return Ray3d{CenterInWorld(), world_from_cam * *direction_in_cam};
}

}  // namespace mirrorscan

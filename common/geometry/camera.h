#pragma once

#include <optional>

#include <Eigen/Core>

#include "common/geometry/plane.h"
#include "common/geometry/rigid3.h"

namespace mirrorscan {

// OpenCV's pinhole model with Brown–Conrady distortion (k1, k2, p1, p2, k3).
// Pixel (u, v): u right, v down, integer values at pixel centres.
struct CameraIntrinsics {
  int width = 1024;
  int height = 768;
  double fx = 1000.0;
  double fy = 1000.0;
  double cx = 511.5;
  double cy = 383.5;
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0, k3 = 0.0;

  Eigen::Matrix3d K() const;
  bool HasDistortion() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0 || k3 != 0; }

  // Normalised image coordinates (x/z, y/z) to their distorted counterpart.
  Eigen::Vector2d Distort(const Eigen::Vector2d& undistorted) const;
  // Inverse of Distort by fixed-point iteration (as cv::undistortPoints, run to
  // convergence); nullopt if it does not converge (far outside the valid field).
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& distorted) const;

  // Point in camera coordinates to pixel; nullopt behind the camera.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_cam) const;
  // Pixel to unit-length viewing direction in camera coordinates.
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& pixel) const;

  bool InImage(const Eigen::Vector2d& pixel, double margin = 0.0) const {
    return pixel.x() >= -0.5 + margin && pixel.y() >= -0.5 + margin &&
           pixel.x() <= width - 0.5 - margin && pixel.y() <= height - 0.5 - margin;
  }
};

// Rays through many pixels of one camera: its pose turned into a rotation matrix and a
// centre once.
struct CameraRays {
  CameraIntrinsics intrinsics;
  Eigen::Matrix3d world_from_cam_rotation;
  Eigen::Vector3d center_in_world;
  std::optional<Ray3d> Through(const Eigen::Vector2d& pixel) const;
};

struct Camera {
  CameraIntrinsics intrinsics;
  Rigid3d cam_from_world;

  Eigen::Vector3d CenterInWorld() const { return cam_from_world.Inverse().translation; }
  std::optional<Eigen::Vector2d> ProjectWorld(const Eigen::Vector3d& point_in_world) const {
    return intrinsics.Project(cam_from_world * point_in_world);
  }
  // Projection through a planar mirror: the point is reflected first.
  std::optional<Eigen::Vector2d> ProjectViaMirror(const Eigen::Vector3d& point_in_world,
                                                  const Plane& mirror) const {
    return ProjectWorld(mirror.ReflectPoint(point_in_world));
  }
  // World ray through a pixel, starting at the camera centre.
  std::optional<Ray3d> RayThroughPixel(const Eigen::Vector2d& pixel) const;
  CameraRays RaysThroughPixels() const;
};

}  // namespace mirrorscan

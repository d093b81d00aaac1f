#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mirrorscan {

// A proper rigid transform b_from_a: point_in_b = rotation * point_in_a + translation.
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& r, const Eigen::Vector3d& t)
      : rotation(r.normalized()), translation(t) {}

  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const {
    return rotation * point + translation;
  }
  // (c_from_b * b_from_a) = c_from_a.
  Rigid3d operator*(const Rigid3d& b_from_a) const {
    return Rigid3d(rotation * b_from_a.rotation, rotation * b_from_a.translation + translation);
  }
  Rigid3d Inverse() const;
  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
  Eigen::Matrix<double, 3, 4> Matrix() const;
};

// Camera pose looking from `eye` at `target` with world z up: camera x right, y down,
// z forward (OpenCV). Returns cam_from_world.
Rigid3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
               const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

}  // namespace mirrorscan

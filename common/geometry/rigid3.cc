#include "common/geometry/rigid3.h"

#include <stdexcept>

namespace mirrorscan {

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inverse_rotation = rotation.conjugate();
  return Rigid3d(inverse_rotation, -(inverse_rotation * translation));
}

Eigen::Matrix<double, 3, 4> Rigid3d::Matrix() const {
  Eigen::Matrix<double, 3, 4> m;
  m.leftCols<3>() = RotationMatrix();
  m.col(3) = translation;
  return m;
}

Rigid3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
               const Eigen::Vector3d& up) {
  const Eigen::Vector3d forward = (target - eye).normalized();
  Eigen::Vector3d right = forward.cross(up);
  if (right.norm() < 1e-9) throw std::invalid_argument("LookAt: view direction parallel to up");
  right.normalize();
  const Eigen::Vector3d down = forward.cross(right);
  // Rows of world_from_cam's transpose: camera axes expressed in world coordinates.
  Eigen::Matrix3d cam_from_world_rotation;
  cam_from_world_rotation.row(0) = right;
  cam_from_world_rotation.row(1) = down;
  cam_from_world_rotation.row(2) = forward;
  const Eigen::Quaterniond rotation(cam_from_world_rotation);
  return Rigid3d(rotation, -(rotation * eye));
}

}  // namespace mirrorscan

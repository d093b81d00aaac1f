#include "common/geometry/plane.h"

#include <cmath>
#include <stdexcept>

namespace mirrorscan {

Plane Plane::FromPointNormal(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) {
  const double norm = normal.norm();
  if (!(norm > 0.0)) throw std::invalid_argument("Plane: zero normal");
  Plane plane;
  plane.normal = normal / norm;
  plane.offset = -plane.normal.dot(point);
  return plane;
}

Plane Plane::Bisector(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return FromPointNormal(0.5 * (a + b), a - b);
}

Eigen::Matrix4d Plane::ReflectionMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() -= 2.0 * normal * normal.transpose();
  m.topRightCorner<3, 1>() = -2.0 * offset * normal;
  return m;
}

}  // namespace mirrorscan

#pragma once

#include <cmath>
#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mirrorscan {

struct Ray3d {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // unit length

  Eigen::Vector3d At(double t) const { return origin + t * direction; }
};

// Plane in Hessian normal form: normal · x + offset = 0, normal of unit length.
// A mirror's normal points towards the subject; a laser plane z = h has normal +z and
// offset -h.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0.0;

  static Plane FromPointNormal(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);
  // Eq. (1) of the paper: the plane midway between two points, its normal towards `a`.
  static Plane Bisector(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

  double SignedDistance(const Eigen::Vector3d& point) const { return normal.dot(point) + offset; }
  Eigen::Vector3d Project(const Eigen::Vector3d& point) const {
    return point - SignedDistance(point) * normal;
  }
  Eigen::Vector3d ReflectPoint(const Eigen::Vector3d& point) const {
    return point - 2.0 * SignedDistance(point) * normal;
  }
  Eigen::Vector3d ReflectDirection(const Eigen::Vector3d& direction) const {
    return direction - 2.0 * normal.dot(direction) * normal;
  }
  Ray3d ReflectRay(const Ray3d& ray) const {
    return {ReflectPoint(ray.origin), ReflectDirection(ray.direction)};
  }
  // The reflection as a 4x4 homogeneous matrix (an improper transform, det = -1).
  Eigen::Matrix4d ReflectionMatrix() const;
};

// Ray parameter t >= t_min where the ray meets the plane; nullopt when parallel or behind.
// Inline: the reconstruction calls it some twenty million times per sweep.
inline std::optional<double> IntersectRayPlane(const Ray3d& ray, const Plane& plane,
                                               double t_min = 0.0) {
  const double denominator = plane.normal.dot(ray.direction);
  if (std::abs(denominator) < 1e-12) return std::nullopt;
  const double t = -plane.SignedDistance(ray.origin) / denominator;
  if (!(t >= t_min)) return std::nullopt;
  return t;
}

}  // namespace mirrorscan

#include "host/reconstruction/bounding_cylinder.h"

#include <algorithm>

namespace mirrorscan::reconstruction {

bool BoundingCylinder::Contains(const Eigen::Vector3d& point) const {
  if (point.z() < bottom_mm || point.z() > top_mm) return false;
  return (point.head<2>() - center_mm).squaredNorm() <= radius_mm * radius_mm;
}

bool BoundingCylinder::OnFloor(const Eigen::Vector3d& point) const {
  if (point.z() >= bottom_mm || point.z() < -std::max(bottom_mm, 20.0)) return false;
  return (point.head<2>() - center_mm).squaredNorm() <= radius_mm * radius_mm;
}

bool BoundingCylinder::CoreContains(const Eigen::Vector3d& point) const {
  if (point.z() < bottom_mm || point.z() > top_mm) return false;
  const double r = std::min(core_radius_mm, radius_mm);
  return (point.head<2>() - center_mm).squaredNorm() <= r * r;
}

}  // namespace mirrorscan::reconstruction

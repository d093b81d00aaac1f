#pragma once
// The volume a subject can stand in (docs/reconstruction.md, stage 2).
#include <Eigen/Core>

namespace mirrorscan::reconstruction {

// A vertical cylinder about the cabinet's axis that holds the subject: a laser hypothesis
// whose point falls outside it is rejected, and so is any output point. Within its core
// (core_radius_mm) stands the body itself: a peak with one hypothesis there and no other
// camera's word against it is decided alone; out to radius_mm reach the hands. A board
// gives its own in board.json (host/board/board_config.h).
struct BoundingCylinder {
  Eigen::Vector2d center_mm = Eigen::Vector2d::Zero();
  double radius_mm = 850.0;
  double core_radius_mm = 450.0;
  double bottom_mm = 10.0;
  double top_mm = 2100.0;
  bool Contains(const Eigen::Vector3d& point) const;
  bool CoreContains(const Eigen::Vector3d& point) const;
  // Below the bottom, down to the floor (z 0) and a little under it.
  bool OnFloor(const Eigen::Vector3d& point) const;
};

}  // namespace mirrorscan::reconstruction

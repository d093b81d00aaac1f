#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace mirrorscan {

// The view a point was seen in: directly, in one mirror, or through both mirrors (the
// first named mirror met first). Values as in the virtual cabinet's truth.
enum class PointView : uint8_t {
  kCenter = 0,
  kLeft = 1,
  kRight = 2,
  kLeftRight = 3,
  kRightLeft = 4
};

// Which correspondence rule gave a point its view and laser (docs/reconstruction.md).
enum class DecidedBy : uint8_t {
  kCylinder = 0,
  kVolume = 1,
  kColumnCount = 2,
  kLabelVote = 3,
  kStereo = 4
};

// One point of a scan's cloud: where it is, which way the surface faces, and where it came
// from. A cloud read from another program's PLY has the position and normal only (the rest
// zero).
struct CloudPoint {
  Eigen::Vector3f point_in_world = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();  // unit, towards the (mirrored) camera
  uint8_t camera = 0;                                // FrameRecord::camera
  PointView view = PointView::kCenter;
  uint8_t laser = 0;
  uint32_t frame = 0;    // the frame's sequence number (FrameRecord::sequence)
  float u = 0;           // image column of the peak
  float v = 0;           // sub-pixel row of the peak
  float confidence = 0;  // in [0, 1]
  DecidedBy rule = DecidedBy::kCylinder;
};

// The project's one point cloud: what reconstruction makes, meshing and the previews use.
struct PointCloud {
  std::vector<CloudPoint> points;
};

}  // namespace mirrorscan

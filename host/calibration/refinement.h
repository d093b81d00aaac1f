// Step 3 of the calibration: every camera and both mirrors refined jointly (Ceres) on the
// target's corners and marker edges. Internal to host/calibration.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/geometry/camera.h"
#include "host/calibration/detection.h"

namespace mirrorscan::calibration::internal {

struct CameraParameters {
  std::array<double, 9> intrinsics;
  std::array<double, 4> rotation;  // Eigen order x, y, z, w
  std::array<double, 3> translation;

  static CameraParameters From(const Camera& camera) {
    const CameraIntrinsics& k = camera.intrinsics;
    CameraParameters p;
    p.intrinsics = {k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2, k.k3};
    const Eigen::Quaterniond& q = camera.cam_from_world.rotation;
    p.rotation = {q.x(), q.y(), q.z(), q.w()};
    p.translation = {camera.cam_from_world.translation.x(), camera.cam_from_world.translation.y(),
                     camera.cam_from_world.translation.z()};
    return p;
  }
  Camera ToCamera(int width, int height) const {
    Camera c;
    CameraIntrinsics& k = c.intrinsics;
    k.width = width;
    k.height = height;
    k.fx = intrinsics[0], k.fy = intrinsics[1], k.cx = intrinsics[2], k.cy = intrinsics[3];
    k.k1 = intrinsics[4], k.k2 = intrinsics[5], k.p1 = intrinsics[6], k.p2 = intrinsics[7];
    k.k3 = intrinsics[8];
    c.cam_from_world =
        Rigid3d(Eigen::Quaterniond(rotation[3], rotation[0], rotation[1], rotation[2]),
                {translation[0], translation[1], translation[2]});
    return c;
  }
};

struct MirrorParameters {
  std::array<double, 3> normal;
  double offset = 0.0;
};

// False when the solver gives up with nothing usable.
bool Refine(const std::vector<CameraData>& data, std::vector<CameraParameters>& cameras,
            std::array<MirrorParameters, 2>& mirrors);

}  // namespace mirrorscan::calibration::internal

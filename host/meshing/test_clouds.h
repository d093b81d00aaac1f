#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "host/meshing/meshing.h"

// Test support only (links the virtual cabinet): clouds made from the sim's truth, for the
// meshing and preview tests before and beside the reconstruction.
namespace mirrorscan::meshing::testing_clouds {

struct TruthCloud {
  PointCloud cloud;                           // noisy points, true normals, camera and view
  std::vector<Eigen::Vector3d> exact_points;  // the same points without noise
  TriangleMesh surface;                       // the subject's true surface
};

// The mannequin scene's exact laser-lit stripe points (every `frame_step`-th frame, both
// cameras, the three single-bounce views), with the subject's surface normal and
// Gaussian noise of sigma `noise_mm` along it.
TruthCloud MannequinTruthCloud(double noise_mm, int frame_step);
// The mannequin scene's subject surface alone.
TriangleMesh MannequinSurface();

// Each point's distance to the surface (Open3D's RaycastingScene, in float).
std::vector<float> DistancesTo(const TriangleMesh& surface,
                               const std::vector<Eigen::Vector3d>& points);

}  // namespace mirrorscan::meshing::testing_clouds

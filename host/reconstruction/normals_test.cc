#include "host/reconstruction/normals.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// On the cuboid's faces the normals from the (column, frame) grid are the analytic faces'
// normals, and every normal faces the camera, or its mirror image, that saw the point.
TEST(Normals, AreTheFacesNormalsAndFaceTheViewpoint) {
  const Sweep& sweep = CuboidSweep();
  const Reconstruction r = Reconstruct(sweep.archive, sweep.calibration);
  size_t on_faces = 0, off_face = 0, matched = 0, away = 0;
  for (const CloudPoint& p : r.cloud.points) {
    const Eigen::Vector3d point = p.point_in_world.cast<double>();
    const Eigen::Vector3d normal = p.normal.cast<double>();
    EXPECT_NEAR(normal.norm(), 1.0, 1e-5);
    // A point of a wrong laser or view (the tripod's pole in the lower camera's top rows,
    // Reconstruct.CuboidThroughTheTrueCalibration...) faces the view it was given instead.
    const TruthPeak* t = Match(sweep, p);
    if (t && t->laser == p.laser && static_cast<int>(t->view) == static_cast<int>(p.view)) {
      ++matched;
      Eigen::Vector3d eye = sweep.scene.cameras[p.camera].camera.CenterInWorld();
      for (int m : virtual_cabinet::MirrorPath(t->view))
        eye = sweep.scene.mirrors[m].plane.ReflectPoint(eye);
      if (normal.dot(eye - point) <= 0) ++away;
    }
    const auto box = DistanceToCuboid(sweep.scene, point);
    if (!box || box->near_edge) continue;
    ++on_faces;
    if (normal.dot(box->normal) < std::cos(10 * M_PI / 180)) ++off_face;
  }
  std::printf("%zu points on the faces, %zu normals more than 10° off; %zu matched, %zu away\n",
              on_faces, off_face, matched, away);
  EXPECT_GT(on_faces, r.cloud.points.size() / 2);
  EXPECT_LE(off_face, on_faces / 25);  // the saturated front face (Reconstruct.Cuboid...)
  EXPECT_GT(matched, r.cloud.points.size() * 9 / 10);
  EXPECT_EQ(away, 0u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

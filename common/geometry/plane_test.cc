#include "common/geometry/plane.h"

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

TEST(PlaneTest, ReflectPointIsInvolutionAndPreservesDistance) {
  const Plane mirror = Plane::FromPointNormal({0, 700, 0}, {0.5, -0.8660254037844386, 0});
  const Eigen::Vector3d p(100, -50, 1200);
  const Eigen::Vector3d q = mirror.ReflectPoint(p);
  EXPECT_NEAR(mirror.SignedDistance(q), -mirror.SignedDistance(p), 1e-9);
  EXPECT_LT((mirror.ReflectPoint(q) - p).norm(), 1e-9);
  EXPECT_LT((mirror.Project(p) - mirror.Project(q)).norm(), 1e-9);
}

TEST(PlaneTest, ReflectedRayPassesThroughReflectedPoints) {
  const Plane mirror = Plane::FromPointNormal({10, 20, 30}, {0.3, -0.9, 0.1});
  const Ray3d ray{{1, 2, 3}, Eigen::Vector3d(0.2, 0.9, -0.1).normalized()};
  const Ray3d reflected = mirror.ReflectRay(ray);
  const Eigen::Vector3d on_ray = ray.At(250.0);
  EXPECT_LT((reflected.At(250.0) - mirror.ReflectPoint(on_ray)).norm(), 1e-9);
  EXPECT_NEAR(reflected.direction.norm(), 1.0, 1e-12);
}

TEST(PlaneTest, ReflectionMatrixMatchesReflectPointAndHasNegativeDeterminant) {
  const Plane mirror = Plane::FromPointNormal({0, 500, 0}, {-0.5, -0.8660254037844386, 0});
  const Eigen::Matrix4d m = mirror.ReflectionMatrix();
  EXPECT_NEAR(m.determinant(), -1.0, 1e-12);
  const Eigen::Vector3d p(-300, 100, 800);
  EXPECT_LT(((m * p.homogeneous()).head<3>() - mirror.ReflectPoint(p)).norm(), 1e-9);
}

TEST(PlaneTest, BisectorIsEquidistantAndNormalPointsToFirst) {
  const Eigen::Vector3d a(0, -2000, 1500), b(1500, 1000, 1500);
  const Plane plane = Plane::Bisector(a, b);
  EXPECT_NEAR(plane.SignedDistance(a), -plane.SignedDistance(b), 1e-9);
  EXPECT_GT(plane.SignedDistance(a), 0);
  EXPECT_LT((plane.ReflectPoint(a) - b).norm(), 1e-9);
}

TEST(PlaneTest, RayPlaneIntersection) {
  const Plane laser{{0, 0, 1}, -1000.0};  // z = 1000
  const Ray3d ray{{0, -2000, 1500}, Eigen::Vector3d(0, 2000, -500).normalized()};
  const auto t = IntersectRayPlane(ray, laser);
  ASSERT_TRUE(t);
  EXPECT_NEAR(ray.At(*t).z(), 1000.0, 1e-9);
  EXPECT_NEAR(ray.At(*t).y(), 0.0, 1e-9);
  EXPECT_FALSE(IntersectRayPlane({{0, 0, 0}, {1, 0, 0}}, laser));   // parallel
  EXPECT_FALSE(IntersectRayPlane({{0, 0, 0}, {0, 0, -1}}, laser));  // behind
}

}  // namespace
}  // namespace mirrorscan

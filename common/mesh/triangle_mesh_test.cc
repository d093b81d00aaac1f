#include "common/mesh/triangle_mesh.h"

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

// Unit tetrahedron, counter-clockwise seen from outside.
TriangleMesh Tetrahedron() {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

double SignedVolume(const TriangleMesh& mesh) {
  double volume = 0.0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]])) / 6.0;
  }
  return volume;
}

TEST(MeshTest, TetrahedronNormalsPointOut) {
  const TriangleMesh mesh = Tetrahedron();
  EXPECT_NEAR(SignedVolume(mesh), 1.0 / 6.0, 1e-15);
  EXPECT_TRUE(mesh.TriangleNormal(0).isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_TRUE(mesh.TriangleNormal(3).isApprox(Eigen::Vector3d(1, 1, 1).normalized()));
}

TEST(MeshTest, AppendOffsetsIndices) {
  TriangleMesh mesh = Tetrahedron();
  TriangleMesh other = Tetrahedron();
  other.Transform(Eigen::Affine3d(Eigen::Translation3d(5, 0, 0)));
  mesh.Append(other);
  ASSERT_EQ(mesh.vertices.size(), 8u);
  ASSERT_EQ(mesh.triangles.size(), 8u);
  EXPECT_EQ(mesh.triangles[4], Eigen::Vector3i(4, 6, 5));
  EXPECT_EQ(mesh.vertices[mesh.triangles[7][0]], Eigen::Vector3d(6, 0, 0));
  EXPECT_NEAR(SignedVolume(mesh), 2.0 / 6.0, 1e-12);
}

TEST(MeshTest, MirroringTransformKeepsNormalsOutward) {
  TriangleMesh mesh = Tetrahedron();
  mesh.Transform(Eigen::Affine3d(Eigen::Scaling(Eigen::Vector3d(-2, 1, 1))));
  EXPECT_EQ(mesh.vertices[1], Eigen::Vector3d(-2, 0, 0));
  EXPECT_NEAR(SignedVolume(mesh), 2.0 / 6.0, 1e-15);  // positive: still outward
  EXPECT_TRUE(mesh.TriangleNormal(0).isApprox(Eigen::Vector3d(0, 0, -1)));
}

TEST(MeshTest, RotationKeepsWindingAndMovesNormals) {
  TriangleMesh mesh = Tetrahedron();
  mesh.Transform(Eigen::Affine3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())));
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 2, 1));
  EXPECT_NEAR(SignedVolume(mesh), 1.0 / 6.0, 1e-15);
  // Face z = 0 (normal -z) rotated +90 degrees about x has normal +y.
  EXPECT_TRUE(mesh.TriangleNormal(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
}

TEST(MeshTest, TransformTurnsVertexNormalsAndAppendKeepsThemOnlyFromBoth) {
  TriangleMesh mesh = Tetrahedron();
  mesh.vertex_normals.assign(4, Eigen::Vector3d(1, 1, 0).normalized());
  // Squeezed along x: a normal of the 45-degree face leans towards x (the inverse
  // transpose), not away from it as a point would.
  mesh.Transform(Eigen::Affine3d(Eigen::Scaling(Eigen::Vector3d(0.5, 1, 1))));
  EXPECT_TRUE(mesh.vertex_normals[0].isApprox(Eigen::Vector3d(2, 1, 0).normalized(), 1e-12));
  TriangleMesh both = mesh;
  both.Append(mesh);
  EXPECT_EQ(both.vertex_normals.size(), 8u);
  EXPECT_TRUE(both.HasVertexNormals());
  both.Append(Tetrahedron());
  EXPECT_TRUE(both.vertex_normals.empty());
  EXPECT_EQ(both.vertices.size(), 12u);
}

TEST(MeshTest, Bounds) {
  EXPECT_TRUE(TriangleMesh().Bounds().isEmpty());
  TriangleMesh mesh = Tetrahedron();
  mesh.Transform(Eigen::Affine3d(Eigen::Translation3d(1, -2, 3)));
  const Eigen::AlignedBox3d box = mesh.Bounds();
  EXPECT_EQ(box.min(), Eigen::Vector3d(1, -2, 3));
  EXPECT_EQ(box.max(), Eigen::Vector3d(2, -1, 4));
  EXPECT_FALSE(mesh.empty());
  EXPECT_TRUE(TriangleMesh().empty());
}

}  // namespace
}  // namespace mirrorscan

#include "boards/virtual/mesh.h"

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "boards/virtual/mesh_io.h"

namespace mirrorscan::virtual_cabinet {
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

class MeshIoTest : public ::testing::TestWithParam<std::string> {};

// Open3D writes, Open3D reads: every format keeps the triangles' corners and winding
// (STL stores no shared vertices, so compare corner by corner).
TEST_P(MeshIoTest, RoundTrip) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / ("mesh_io_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path file = dir / ("tetra" + GetParam());
  TriangleMesh mesh = Tetrahedron();
  mesh.Transform(Eigen::Affine3d(Eigen::Translation3d(10, 20, 30)));
  WriteMeshFile(mesh, file);
  const TriangleMesh back = ReadMeshFile(file);
  ASSERT_EQ(back.triangles.size(), 4u);
  for (int t = 0; t < 4; ++t) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(
          back.vertices[back.triangles[t][k]].isApprox(mesh.vertices[mesh.triangles[t][k]], 1e-6))
          << GetParam() << " triangle " << t << " corner " << k;
    }
  }
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Formats, MeshIoTest, ::testing::Values(".ply", ".obj", ".stl"));

TEST(MeshIoErrorTest, NamesTheFileAndTheProblem) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / ("mesh_io_error_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  try {
    ReadMeshFile(dir / "missing.ply");
    FAIL() << "no error";
  } catch (const MeshIoError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "missing.ply").string() + ": no such file");
  }
  std::ofstream(dir / "garbage.ply") << "this is not a ply file\n";
  EXPECT_THROW(ReadMeshFile(dir / "garbage.ply"), MeshIoError);
  std::ofstream(dir / "x.xyz") << "0 0 0\n";
  try {
    ReadMeshFile(dir / "x.xyz");
    FAIL() << "no error";
  } catch (const MeshIoError& e) {
    EXPECT_NE(std::string(e.what()).find("unsupported mesh format \".xyz\""), std::string::npos)
        << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

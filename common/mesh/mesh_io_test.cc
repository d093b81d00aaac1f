#include "common/mesh/mesh_io.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;

// Unit tetrahedron moved to (10, 20, 30), counter-clockwise seen from outside.
TriangleMesh Tetrahedron() {
  TriangleMesh mesh;
  mesh.vertices = {{10, 20, 30}, {11, 20, 30}, {10, 21, 30}, {10, 20, 31}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("mesh_io_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path Write(const std::string& name, const std::string& bytes) const {
    std::ofstream(dir_ / name, std::ios::binary) << bytes;
    return dir_ / name;
  }
  static std::string Read(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    return bytes.str();
  }
  // The message of the MeshIoError that reading `file` throws.
  static std::string ReadError(const fs::path& file) {
    try {
      ReadTriangleMesh(file);
    } catch (const MeshIoError& e) {
      return e.what();
    }
    return "no error";
  }

  fs::path dir_;
};

// Every corner of every triangle where it was, in the same winding.
void ExpectSameTriangles(const TriangleMesh& back, const TriangleMesh& mesh, double tolerance) {
  ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE((back.vertices[back.triangles[t][k]] - mesh.vertices[mesh.triangles[t][k]]).norm(),
                tolerance)
          << "triangle " << t << " corner " << k;
    }
  }
}

TEST_F(MeshIoTest, EveryFormatRoundTrips) {
  TriangleMesh mesh = Tetrahedron();
  mesh.vertices[1].x() = 11.123456789;
  for (const std::string name : {"tetra.ply", "tetra.obj", "tetra.stl", "TETRA.PLY"}) {
    SCOPED_TRACE(name);
    WriteTriangleMesh(mesh, dir_ / name);
    const TriangleMesh back = ReadTriangleMesh(dir_ / name);
    EXPECT_EQ(back.vertices.size(), 4u);  // STL's twelve corners welded into four vertices
    // PLY keeps doubles, STL floats, OBJ six significant digits.
    ExpectSameTriangles(back, mesh, name == "tetra.obj" ? 1e-4 : name == "tetra.stl" ? 1e-5 : 0.0);
  }
}

TEST_F(MeshIoTest, PlyKeepsVertexNormalsAndHasOpen3dsLayout) {
  TriangleMesh mesh = Tetrahedron();
  mesh.vertex_normals = {{0, 0, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  WriteTriangleMesh(mesh, dir_ / "n.ply");
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment Created by Open3D\nelement vertex 4\n"
      "property double x\nproperty double y\nproperty double z\nproperty double nx\n"
      "property double ny\nproperty double nz\nelement face 4\n"
      "property list uchar uint vertex_indices\nend_header\n";
  const std::string bytes = Read(dir_ / "n.ply");
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_EQ(bytes.size(), header.size() + 4 * 48 + 4 * 13);
  const TriangleMesh back = ReadTriangleMesh(dir_ / "n.ply");
  EXPECT_EQ(back.vertices, mesh.vertices);
  EXPECT_EQ(back.vertex_normals, mesh.vertex_normals);
  EXPECT_EQ(back.triangles, mesh.triangles);
}

TEST_F(MeshIoTest, ObjAndStlAsOpen3dWrote) {
  TriangleMesh mesh = Tetrahedron();
  mesh.vertices[3].z() = 31.23456789;
  WriteTriangleMesh(mesh, dir_ / "t.obj");
  EXPECT_EQ(Read(dir_ / "t.obj"),
            "# Created by Open3D \n# object name: t\n# number of vertices: 4\n"
            "# number of triangles: 4\nv 10 20 30\nv 11 20 30\nv 10 21 30\nv 10 20 31.2346\n"
            "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  WriteTriangleMesh(mesh, dir_ / "t.stl");
  const std::string stl = Read(dir_ / "t.stl");
  ASSERT_EQ(stl.size(), 84u + 4 * 50);
  EXPECT_EQ(stl.substr(0, 18), std::string("Created by Open3D\0", 18));
  EXPECT_EQ(stl[80], 4);
  float facet[2][12];
  std::memcpy(facet[0], stl.data() + 84, sizeof facet[0]);
  std::memcpy(facet[1], stl.data() + 84 + 50, sizeof facet[1]);
  // The first triangle lies in z = 30, seen from below: normal -z; then its corners. The
  // second, in y = 20 with an edge 1.23 mm long: a unit normal, -y.
  EXPECT_EQ(Eigen::Vector3f(facet[0][0], facet[0][1], facet[0][2]), Eigen::Vector3f(0, 0, -1));
  EXPECT_EQ(Eigen::Vector3f(facet[0][6], facet[0][7], facet[0][8]), Eigen::Vector3f(10, 21, 30));
  EXPECT_EQ(Eigen::Vector3f(facet[1][0], facet[1][1], facet[1][2]), Eigen::Vector3f(0, -1, 0));
}

TEST_F(MeshIoTest, ReadsAsciiAndBigEndianPlyWithPolygons) {
  // A unit square as one quad and a triangle, among properties and an element we ignore.
  const fs::path ascii = Write("quad.ply",
                               "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\n"
                               "element vertex 5\r\nproperty float x\r\nproperty float y\r\n"
                               "property float z\r\nproperty uchar red\r\n"
                               "element face 2\r\nproperty list uchar int vertex_index\r\n"
                               "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\n"
                               "end_header\r\n"
                               "0 0 0 255\r\n1 0 0 0\r\n1 1 0 0\r\n0 1 0 0\r\n0.5 0.5 +1e0 9\r\n"
                               "4 0 1 2 3\r\n3 0 1 4\r\n0 1\r\n");
  TriangleMesh mesh = ReadTriangleMesh(ascii);
  ASSERT_EQ(mesh.vertices.size(), 5u);
  EXPECT_EQ(mesh.vertices[4], Eigen::Vector3d(0.5, 0.5, 1));
  ASSERT_EQ(mesh.triangles.size(), 3u);
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(0, 1, 4));
  EXPECT_TRUE(mesh.vertex_normals.empty());

  // Big-endian: one triangle, short vertex indices, double coordinates.
  std::string big =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\n"
      "property double y\nproperty double z\nelement face 1\n"
      "property list uchar short vertex_indices\nend_header\n";
  auto put_big = [&big](const auto value) {
    char bytes[sizeof value];
    std::memcpy(bytes, &value, sizeof value);
    for (size_t i = sizeof value; i-- > 0;) big.push_back(bytes[i]);
  };
  for (const double v : {0.0, 0.0, 0.0, 2.5, 0.0, 0.0, 0.0, -1.25, 7.0}) put_big(v);
  put_big(uint8_t{3});
  for (const int16_t i : {0, 1, 2}) put_big(i);
  mesh = ReadTriangleMesh(Write("big.ply", big));
  ASSERT_EQ(mesh.vertices.size(), 3u);
  EXPECT_EQ(mesh.vertices[1], Eigen::Vector3d(2.5, 0, 0));
  EXPECT_EQ(mesh.vertices[2], Eigen::Vector3d(0, -1.25, 7));
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
}

TEST_F(MeshIoTest, ReadsObjCornersOfEveryFormAndNegativeIndices) {
  const fs::path obj = Write("forms.obj",
                             "# a square and a triangle\no square\nv 0 0 0\nv 1 0 0\nv 1 1 0\n"
                             "v 0 1 0 1.0\nvt 0 0\nvn 0 0 1\ns off\n"
                             "f 1/1/1 2/1/1 3//1 4\nv 0.5 0.5 1\nf -5 -4 -1\n");
  const TriangleMesh mesh = ReadTriangleMesh(obj);
  ASSERT_EQ(mesh.vertices.size(), 5u);
  ASSERT_EQ(mesh.triangles.size(), 3u);
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(0, 1, 4));
  EXPECT_EQ(ReadError(Write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")),
            (dir_ / "bad.obj").string() + ": OBJ line 4: bad face corner \"x\"");
}

TEST_F(MeshIoTest, ReadsAsciiStlAndWeldsItsCorners) {
  const fs::path stl = Write("two.stl",
                             "solid two\n"
                             " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n"
                             "   vertex 1 0 0\n   vertex 1 1 0\n  endloop\n endfacet\n"
                             " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n"
                             "   vertex 1 1 0\n   vertex 0 1 0\n  endloop\n endfacet\n"
                             "endsolid two\n");
  const TriangleMesh mesh = ReadTriangleMesh(stl);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.vertices[3], Eigen::Vector3d(0, 1, 0));
}

TEST_F(MeshIoTest, ErrorsNameTheFileAndTheProblem) {
  EXPECT_EQ(ReadError(dir_ / "missing.ply"), (dir_ / "missing.ply").string() + ": no such file");
  EXPECT_EQ(ReadError(Write("garbage.ply", "this is not a ply file\n")),
            (dir_ / "garbage.ply").string() + ": not a PLY file");
  EXPECT_EQ(ReadError(Write("x.xyz", "0 0 0\n")),
            (dir_ / "x.xyz").string() +
                ": unsupported mesh format \".xyz\" (expected .ply, .obj or .stl)");
  EXPECT_EQ(ReadError(Write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")),
            (dir_ / "points.obj").string() + ": mesh has no triangles");
  EXPECT_EQ(ReadError(Write("far.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")),
            (dir_ / "far.obj").string() + ": a triangle refers to a missing vertex");
  EXPECT_EQ(ReadError(Write("nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
            (dir_ / "nan.obj").string() + ": a vertex is not finite");
  EXPECT_EQ(ReadError(Write("odd.stl", std::string(90, 'x'))),
            (dir_ / "odd.stl").string() +
                ": neither a binary STL (90 bytes) nor an ASCII one (\"solid\")");
  // A binary PLY cut short.
  WriteTriangleMesh(Tetrahedron(), dir_ / "whole.ply");
  const std::string whole = Read(dir_ / "whole.ply");
  EXPECT_EQ(
      ReadError(Write("cut.ply", whole.substr(0, whole.size() - 5))),
      (dir_ / "cut.ply").string() + ": cut off or malformed in element \"face\" (row 3 of 4)");
  EXPECT_EQ(ReadError(Write("header.ply", "ply\nformat ascii 1.0\nelement vertex\nend_header\n")),
            (dir_ / "header.ply").string() + ": PLY header line 3: bad element line");
  EXPECT_THROW(WriteTriangleMesh(TriangleMesh(), dir_ / "empty.stl"), MeshIoError);
  EXPECT_THROW(WriteTriangleMesh(Tetrahedron(), dir_ / "no-such-dir" / "t.ply"), MeshIoError);
}

}  // namespace
}  // namespace mirrorscan

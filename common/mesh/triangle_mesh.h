#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mirrorscan {

// The project's one indexed triangle mesh (the virtual cabinet's subjects, the Poisson
// surface, what measurement slices): millimetres, world frame unless stated otherwise.
// Triangles are counter-clockwise seen from outside (normals point out); parts may overlap
// (the mannequin is overlapping closed solids, a scan is one surface). vertex_normals is
// empty or one unit normal per vertex.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Eigen::Vector3d> vertex_normals;

  // Appends other's triangles; the vertex normals stay only if both meshes have them.
  void Append(const TriangleMesh& other);
  // Moves the vertices (and turns the normals); handles mirroring transforms.
  void Transform(const Eigen::Affine3d& transform);
  Eigen::Vector3d TriangleNormal(int triangle) const;  // unit, outward
  Eigen::AlignedBox3d Bounds() const;
  bool empty() const { return triangles.empty(); }
  bool HasVertexNormals() const {
    return !vertices.empty() && vertex_normals.size() == vertices.size();
  }
};

}  // namespace mirrorscan

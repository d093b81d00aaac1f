#pragma once

#include <filesystem>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mirrorscan::virtual_cabinet {

// An indexed triangle mesh in millimetres, world frame unless stated otherwise.
// Triangles are counter-clockwise seen from outside (normals point out).
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;

  void Append(const TriangleMesh& other);
  void Transform(const Eigen::Affine3d& transform);  // handles mirroring transforms
  Eigen::Vector3d TriangleNormal(int triangle) const;  // unit, outward
  Eigen::AlignedBox3d Bounds() const;
  bool empty() const { return triangles.empty(); }
};

}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/mesh.h"

#include <utility>

namespace mirrorscan::virtual_cabinet {

void TriangleMesh::Append(const TriangleMesh& other) {
  const int offset = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  triangles.reserve(triangles.size() + other.triangles.size());
  for (const Eigen::Vector3i& t : other.triangles) {
    triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
}

void TriangleMesh::Transform(const Eigen::Affine3d& transform) {
  for (Eigen::Vector3d& v : vertices) v = transform * v;
  // A mirroring transform turns counter-clockwise into clockwise; swap two corners so
  // the triangles stay counter-clockwise seen from outside.
  if (transform.linear().determinant() < 0.0) {
    for (Eigen::Vector3i& t : triangles) std::swap(t[1], t[2]);
  }
}

Eigen::Vector3d TriangleMesh::TriangleNormal(int triangle) const {
  const Eigen::Vector3i& t = triangles[triangle];
  const Eigen::Vector3d& a = vertices[t[0]];
  return (vertices[t[1]] - a).cross(vertices[t[2]] - a).normalized();
}

Eigen::AlignedBox3d TriangleMesh::Bounds() const {
  Eigen::AlignedBox3d box;  // empty until extended
  for (const Eigen::Vector3d& v : vertices) box.extend(v);
  return box;
}

}  // namespace mirrorscan::virtual_cabinet

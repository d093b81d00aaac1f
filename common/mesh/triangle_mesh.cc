#include "common/mesh/triangle_mesh.h"

#include <utility>

namespace mirrorscan {

void TriangleMesh::Append(const TriangleMesh& other) {
  const bool normals = HasVertexNormals() && other.HasVertexNormals();
  const int offset = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  if (normals) {
    vertex_normals.insert(vertex_normals.end(), other.vertex_normals.begin(),
                          other.vertex_normals.end());
  } else {
    vertex_normals.clear();
  }
  triangles.reserve(triangles.size() + other.triangles.size());
  for (const Eigen::Vector3i& t : other.triangles) {
    triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
}

void TriangleMesh::Transform(const Eigen::Affine3d& transform) {
  for (Eigen::Vector3d& v : vertices) v = transform * v;
  // Normals are covectors: they turn with the inverse transpose (a scaling squeezes them
  // the other way).
  const Eigen::Matrix3d normal_transform = transform.linear().inverse().transpose();
  for (Eigen::Vector3d& n : vertex_normals) n = (normal_transform * n).normalized();
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

}  // namespace mirrorscan

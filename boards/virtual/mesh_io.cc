#include "boards/virtual/mesh_io.h"

#include <algorithm>
#include <cctype>
#include <string>
#include <system_error>

#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>

namespace mirrorscan::virtual_cabinet {
namespace {

std::string Extension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

void CheckExtension(const std::filesystem::path& file) {
  const std::string ext = Extension(file);
  if (ext != ".ply" && ext != ".obj" && ext != ".stl") {
    throw MeshIoError(file.string() + ": unsupported mesh format \"" + ext +
                      "\" (expected .ply, .obj or .stl)");
  }
}

}  // namespace

TriangleMesh ReadMeshFile(const std::filesystem::path& file) {
  CheckExtension(file);
  std::error_code error;
  if (!std::filesystem::exists(file, error)) throw MeshIoError(file.string() + ": no such file");
  if (!std::filesystem::is_regular_file(file, error)) {
    throw MeshIoError(file.string() + ": not a regular file");
  }
  open3d::geometry::TriangleMesh loaded;
  // Open3D reports failures only as a bool (and a console warning), so the reason is
  // ours to guess: the file exists, hence it is unreadable or malformed.
  if (!open3d::io::ReadTriangleMesh(file.string(), loaded)) {
    throw MeshIoError(file.string() + ": cannot read mesh (unreadable or malformed file)");
  }
  if (loaded.triangles_.empty()) throw MeshIoError(file.string() + ": mesh has no triangles");
  const int vertex_count = static_cast<int>(loaded.vertices_.size());
  for (const Eigen::Vector3i& t : loaded.triangles_) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= vertex_count) {
      throw MeshIoError(file.string() + ": triangle refers to a missing vertex");
    }
  }
  for (const Eigen::Vector3d& v : loaded.vertices_) {
    if (!v.allFinite()) throw MeshIoError(file.string() + ": vertex is not finite");
  }
  TriangleMesh mesh;
  mesh.vertices = std::move(loaded.vertices_);
  mesh.triangles = std::move(loaded.triangles_);
  return mesh;
}

void WriteMeshFile(const TriangleMesh& mesh, const std::filesystem::path& file) {
  CheckExtension(file);
  open3d::geometry::TriangleMesh out;
  out.vertices_ = mesh.vertices;
  out.triangles_ = mesh.triangles;
  // STL stores a normal per facet; Open3D refuses to write STL without them.
  if (Extension(file) == ".stl") out.ComputeTriangleNormals();
  if (!open3d::io::WriteTriangleMesh(file.string(), out, /*write_ascii=*/false,
                                     /*compressed=*/false, /*write_vertex_normals=*/false,
                                     /*write_vertex_colors=*/false,
                                     /*write_triangle_uvs=*/false)) {
    throw MeshIoError(file.string() + ": cannot write mesh");
  }
}

}  // namespace mirrorscan::virtual_cabinet

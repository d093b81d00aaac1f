#pragma once
// The project's one reader and writer of mesh and cloud files: PLY, OBJ and STL meshes
// here, the scan's PLY cloud in cloud_io.h.
#include <filesystem>
#include <stdexcept>

#include "common/mesh/triangle_mesh.h"

namespace mirrorscan {

// A mesh or cloud file that cannot be read or written; the message starts with the file
// name and says what is wrong in one line.
class MeshIoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads a mesh by extension (any case): PLY (ASCII or binary; vertex x, y, z and, when
// present, nx, ny, nz; faces as vertex_indices or vertex_index lists), OBJ (v and f lines;
// f corners as v, v/vt, v/vt/vn or v//vn, negative indices from the end; numbers read as
// double) or STL (binary or ASCII; corners at the same position become one vertex, numbered
// in order of first use). OBJ and STL normals are not read. Polygons are cut into triangle
// fans. A missing file, an unknown extension, a malformed file, a mesh without triangles, a
// triangle naming a missing vertex or a vertex that is not finite is a MeshIoError.
TriangleMesh ReadTriangleMesh(const std::filesystem::path& file);

// Writes a mesh by extension: PLY (binary little-endian, double coordinates, the vertex
// normals when the mesh has them), OBJ (with `vn` lines when it has normals) or STL
// (binary, a facet normal per triangle). The bytes are those Open3D 0.16 wrote for the
// same mesh (the files of earlier runs compare equal). A MeshIoError when the extension
// is unknown, the mesh has no triangles (STL) or the file cannot be written.
void WriteTriangleMesh(const TriangleMesh& mesh, const std::filesystem::path& file);

// The file's extension in lower case (".ply").
std::string LowerCaseExtension(const std::filesystem::path& file);

}  // namespace mirrorscan

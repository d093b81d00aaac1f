#pragma once

#include <filesystem>
#include <stdexcept>

#include "boards/virtual/mesh.h"

namespace mirrorscan::virtual_cabinet {

// A mesh file that cannot be read or written; the message starts with the file name.
class MeshIoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads a PLY, OBJ or STL file (chosen by extension). A missing or unreadable file, an
// unknown extension or a file without triangles is a MeshIoError.
TriangleMesh ReadMeshFile(const std::filesystem::path& file);

// Writes a PLY (binary), OBJ or STL (binary) file, chosen by extension.
void WriteMeshFile(const TriangleMesh& mesh, const std::filesystem::path& file);

}  // namespace mirrorscan::virtual_cabinet

#pragma once
// The virtual cabinet's meshes (subjects, the target, the chessboard) are the project's one
// TriangleMesh (common/mesh), read and written by common/mesh/mesh_io.h.
#include "common/mesh/triangle_mesh.h"

namespace mirrorscan::virtual_cabinet {

using mirrorscan::TriangleMesh;

}  // namespace mirrorscan::virtual_cabinet

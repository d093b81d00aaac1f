#pragma once
// The scan's point cloud as a PLY file (points.ply).
#include <filesystem>

#include "common/mesh/mesh_io.h"
#include "common/mesh/point_cloud.h"

namespace mirrorscan {

// Binary little-endian PLY: x y z nx ny nz (float), camera view laser (uchar), frame
// (uint), u v confidence (float), rule (uchar, DecidedBy). A MeshIoError naming the file
// when it cannot be written.
void WritePointCloud(const std::filesystem::path& file, const PointCloud& cloud);

// Reads a PLY point cloud, ASCII or binary: x, y, z of its vertex element and whichever of
// nx ny nz, camera view laser frame u v confidence rule it has (the rest stay zero), so
// what WritePointCloud writes comes back whole and another program's cloud with normals
// can be meshed. A missing or malformed file, one not named .ply, one without x y z, or
// (require_normals) without nx ny nz is a MeshIoError naming the file.
PointCloud ReadPointCloud(const std::filesystem::path& file, bool require_normals = false);

}  // namespace mirrorscan

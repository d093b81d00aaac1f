#pragma once

#include <functional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "boards/virtual/mesh.h"

namespace mirrorscan::virtual_cabinet {

// The zero set of a field (negative inside) as a closed, edge- and vertex-manifold
// triangle mesh, outward normals. The grid of step `cell_mm` over `box` is cut into
// tetrahedra (six per cell along the main diagonal, so neighbouring cells share their face
// diagonals), the surface is the field's piecewise-linear zero set on them, and each vertex
// is then moved along its edge onto the field's own zero (regula falsi), so vertices lie on
// the exact surface. A piecewise-linear zero set on a tetrahedral grid, with no grid value
// exactly zero (zero counts as outside), is a closed 2-manifold by construction, and its
// triangles lie in disjoint tetrahedra, so it cannot intersect itself.
//
// Only cells near the surface are evaluated: blocks of 4x4x4 cells whose corners are all
// farther than `band_mm` from zero on the same side are skipped, so the field must not
// overstate distance by more than band_mm - a block's diagonal. The surface must lie inside
// the box.
//
// Open3D 0.16's only marching cubes sits inside its TSDF volumes (a dense uniform grid:
// 46 GB for a standing body at 2 mm), which is why this is not a library call.
TriangleMesh MeshIsosurface(const std::function<double(const Eigen::Vector3d&)>& field,
                            const Eigen::AlignedBox3d& box, double cell_mm, double band_mm,
                            int threads = 0);

}  // namespace mirrorscan::virtual_cabinet

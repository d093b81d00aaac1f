#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/mesh/point_cloud.h"
#include "common/mesh/triangle_mesh.h"

namespace mirrorscan::meshing {

// The input cannot give a usable mesh (too few points, no normals, a cloud that covers
// too little of a body); what() says why in one line.
class MeshingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct MeshingOptions {
  // Voxel grid the cloud is averaged on before Poisson (0: no downsampling). The stripes
  // are ~1.3 mm apart along a laser line and ~5 mm apart across, so 2 mm thins only the
  // dense direction.
  double voxel_mm = 2.0;
  // Finest Poisson cell: the octree depth is the smallest whose cells over the cloud's
  // bounding cube (times `scale`) are no larger. Ignored when depth > 0.
  double cell_mm = 4.0;
  int depth = 0;
  double scale = 1.1;      // Poisson's bounding cube over the cloud's extent
  bool linear_fit = true;  // iso-surface placed by linear interpolation
  // Poisson's worker threads, never Open3D's default -1 (OpenMP threads spin on a busy
  // machine: 9.6 s vs 65 s measured, and upstream reports crashes with several threads).
  int threads = 1;
  // Trimming of surface the data do not support: a vertex further than this from every
  // input point goes, and so does one whose Poisson density is below the given quantile.
  double trim_distance_mm = 5.0;
  double trim_density_quantile = 0.0;
  // Pieces left after trimming with less than this share of the surface area are dropped
  // (flaps between the legs, islands under the arms, and pieces grown on wrongly
  // triangulated mirror peaks: two of 1.04 % each beside the arms on the demo's scan).
  double min_component_area_share = 0.02;
  // Keep Poisson's closed surface untrimmed (for printing).
  bool watertight = false;
  // Below this many points (after downsampling) no mesh is made.
  int min_points = 2000;
  // A body is seen from the camera and in both mirrors: a cloud with less than this share
  // of its normals facing each of -y, +y, -x, +x (within 45°) covers one view only and is
  // refused. (Mannequin: 43 % face -y, 27 % +y, 15 % each of ±x; with black mirrors +y
  // falls to 2.7 %.)
  double min_direction_share = 0.05;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

// A hole: one closed loop of boundary edges.
struct Hole {
  double perimeter_mm = 0.0;
  int edges = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
};

struct HoleReport {
  std::vector<Hole> holes;      // largest perimeter first
  int open_boundary_edges = 0;  // boundary edges on no closed loop (non-manifold spots)
  int count() const { return static_cast<int>(holes.size()); }
  double largest_perimeter_mm() const { return holes.empty() ? 0.0 : holes[0].perimeter_mm; }
};

struct MeshStats {
  int vertices = 0;
  int triangles = 0;
  int components = 0;
  double area_mm2 = 0.0;
  double volume_mm3 = 0.0;  // only when watertight, else 0
  bool watertight = false;
  bool edge_manifold = false;
  Eigen::AlignedBox3d bounds;
  double mean_edge_mm = 0.0;
};

struct MeshingResult {
  TriangleMesh mesh;  // with vertex normals
  MeshStats stats;
  HoleReport holes;
  int input_points = 0;
  int downsampled_points = 0;
  int depth = 0;         // Poisson octree depth used
  double cell_mm = 0.0;  // its finest cell
  int poisson_vertices = 0;
  int trimmed_far = 0;          // vertices dropped: further than trim_distance_mm
  int trimmed_low_density = 0;  // vertices dropped: density below the quantile
  int dropped_components = 0;   // small pieces dropped after trimming
  double downsample_s = 0.0, poisson_s = 0.0, trim_s = 0.0;
  std::vector<std::string> warnings;
};

// Poisson surface from the cloud's points and their outward normals (Open3D), trimmed
// where the data do not support it unless options.watertight. Throws MeshingError when the
// cloud cannot give a body surface, std::invalid_argument on bad options.
MeshingResult MeshCloud(const PointCloud& cloud, const MeshingOptions& options);

// Closed loops of edges used by one triangle only.
HoleReport FindHoles(const TriangleMesh& mesh);
MeshStats ComputeStats(const TriangleMesh& mesh);

// The result for summaries (summary.json's "mesh", `mesh --json`): points, Poisson depth
// and cell, what trimming dropped, the mesh's statistics, holes, timings and warnings.
nlohmann::json SummaryJson(const MeshingResult& result);

// The Open3D version meshing was built against ("0.16.1").
std::string Open3dVersion();

}  // namespace mirrorscan::meshing

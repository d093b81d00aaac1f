#include "host/meshing/meshing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>
#include <unordered_map>

#include <open3d/Open3DConfig.h>
#include <open3d/geometry/BoundingVolume.h>
#include <open3d/geometry/KDTreeFlann.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/geometry/TriangleMesh.h>

namespace mirrorscan::meshing {
namespace {

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string Percent(double share) {
  std::ostringstream out;
  out.precision(1);
  out << std::fixed << 100.0 * share << " %";
  return out.str();
}

// A body seen by the camera and both mirrors has surface facing every way round; one
// view alone leaves a whole side out (the camera sees no back, a mirror no far side).
void CheckCoverage(const open3d::geometry::PointCloud& cloud, double min_share) {
  static const Eigen::Vector2d kDirections[] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
  static const char* kNames[] = {"the camera (-y)", "the mirrors (+y)", "-x", "+x"};
  std::array<int, 4> facing{};
  for (const Eigen::Vector3d& n : cloud.normals_) {
    const double horizontal = n.head<2>().norm();
    if (horizontal < 0.3) continue;
    for (int d = 0; d < 4; ++d) {
      // Within 45° of the direction, horizontally.
      if (n.head<2>().dot(kDirections[d]) > std::sqrt(0.5) * horizontal) ++facing[d];
    }
  }
  const double total = static_cast<double>(cloud.points_.size());
  for (int d = 0; d < 4; ++d) {
    if (facing[d] < min_share * total) {
      throw MeshingError("the cloud does not go round a body: " + Percent(facing[d] / total) +
                         " of its points face " + kNames[d] + " (-y " + Percent(facing[0] / total) +
                         ", +y " + Percent(facing[1] / total) + ", -x " +
                         Percent(facing[2] / total) + ", +x " + Percent(facing[3] / total) +
                         "); is a view missing from the scan or the calibration?");
    }
  }
}

TriangleMesh FromOpen3d(const open3d::geometry::TriangleMesh& in) {
  TriangleMesh mesh;
  mesh.vertices = in.vertices_;
  mesh.triangles = in.triangles_;
  mesh.vertex_normals = in.vertex_normals_;
  return mesh;
}

open3d::geometry::TriangleMesh ToOpen3d(const TriangleMesh& in) {
  open3d::geometry::TriangleMesh mesh;
  mesh.vertices_ = in.vertices;
  mesh.triangles_ = in.triangles;
  mesh.vertex_normals_ = in.vertex_normals;
  return mesh;
}

// Drops the connected pieces with less than `min_share` of the area (all but the largest
// when min_share >= 1); returns how many went.
int DropSmallComponents(open3d::geometry::TriangleMesh* mesh, double min_share) {
  if (mesh->triangles_.empty()) return 0;
  const auto [cluster_of_triangle, triangles_per_cluster, area_per_cluster] =
      mesh->ClusterConnectedTriangles();
  const double total = std::accumulate(area_per_cluster.begin(), area_per_cluster.end(), 0.0);
  const auto largest =
      std::max_element(area_per_cluster.begin(), area_per_cluster.end()) - area_per_cluster.begin();
  std::vector<bool> drop_cluster(area_per_cluster.size());
  int dropped = 0;
  for (size_t c = 0; c < area_per_cluster.size(); ++c) {
    const bool keep = static_cast<long>(c) == largest ||
                      (min_share < 1.0 && area_per_cluster[c] >= min_share * total);
    drop_cluster[c] = !keep;
    dropped += keep ? 0 : 1;
  }
  std::vector<bool> drop_triangle(mesh->triangles_.size());
  for (size_t t = 0; t < drop_triangle.size(); ++t) {
    drop_triangle[t] = drop_cluster[cluster_of_triangle[t]];
  }
  mesh->RemoveTrianglesByMask(drop_triangle);
  mesh->RemoveUnreferencedVertices();
  return dropped;
}

}  // namespace

void MeshingOptions::Validate() const {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument("meshing: " + what);
  };
  require(voxel_mm >= 0 && std::isfinite(voxel_mm), "voxel_mm must be >= 0");
  require(depth == 0 || (depth >= 4 && depth <= 12), "depth must be 0 (from cell_mm) or 4..12");
  require(depth > 0 || (cell_mm > 0 && std::isfinite(cell_mm)), "cell_mm must be > 0");
  require(scale >= 1.0 && scale <= 2.0, "scale must be in [1, 2]");
  require(threads >= 1 && threads <= 64, "threads must be in [1, 64]");
  require(trim_distance_mm > 0, "trim_distance_mm must be > 0");
  require(trim_density_quantile >= 0 && trim_density_quantile < 0.5,
          "trim_density_quantile must be in [0, 0.5)");
  require(min_component_area_share >= 0 && min_component_area_share < 1,
          "min_component_area_share must be in [0, 1)");
  require(min_points >= 100, "min_points must be >= 100");
  require(min_direction_share >= 0 && min_direction_share < 0.34,
          "min_direction_share must be in [0, 0.34)");
}

MeshingResult MeshCloud(const PointCloud& cloud, const MeshingOptions& options) {
  options.Validate();
  MeshingResult result;
  result.input_points = static_cast<int>(cloud.points.size());

  auto start = Clock::now();
  open3d::geometry::PointCloud input;
  input.points_.reserve(cloud.points.size());
  input.normals_.reserve(cloud.points.size());
  for (const CloudPoint& p : cloud.points) {
    const Eigen::Vector3d point = p.point_in_world.cast<double>();
    const Eigen::Vector3d normal = p.normal.cast<double>();
    const double normal_length = normal.norm();
    if (!point.allFinite() || !std::isfinite(normal_length) || normal_length < 0.5) {
      continue;  // a point without a usable normal cannot orient the surface
    }
    input.points_.push_back(point);
    input.normals_.push_back(normal / normal_length);
  }
  if (input.points_.size() < cloud.points.size()) {
    result.warnings.push_back(std::to_string(cloud.points.size() - input.points_.size()) +
                              " points without a finite unit normal were ignored");
  }
  std::shared_ptr<open3d::geometry::PointCloud> points =
      options.voxel_mm > 0 ? input.VoxelDownSample(options.voxel_mm)
                           : std::make_shared<open3d::geometry::PointCloud>(input);
  points->NormalizeNormals();
  result.downsampled_points = static_cast<int>(points->points_.size());
  result.downsample_s = SecondsSince(start);
  if (result.downsampled_points < options.min_points) {
    throw MeshingError(
        "too few points for a surface: " + std::to_string(result.downsampled_points) +
        " after downsampling (" + std::to_string(result.input_points) +
        " in the cloud), at least " + std::to_string(options.min_points) + " needed");
  }
  CheckCoverage(*points, options.min_direction_share);

  start = Clock::now();
  // Poisson's surface ends where it meets its bounding cube; for a closed surface the
  // cube must leave room for the bulges that close the unseen parts (soles, head).
  const double scale = options.watertight ? std::max(options.scale, 1.5) : options.scale;
  const double extent = points->GetAxisAlignedBoundingBox().GetMaxExtent() * scale;
  result.depth =
      options.depth > 0
          ? options.depth
          : std::clamp(static_cast<int>(std::ceil(std::log2(extent / options.cell_mm))), 4, 12);
  result.cell_mm = extent / std::exp2(result.depth);
  auto [poisson, densities] = open3d::geometry::TriangleMesh::CreateFromPointCloudPoisson(
      *points, static_cast<size_t>(result.depth), /*width=*/0.0f, static_cast<float>(scale),
      options.linear_fit, options.threads);
  result.poisson_s = SecondsSince(start);
  result.poisson_vertices = static_cast<int>(poisson->vertices_.size());
  if (poisson->triangles_.empty()) throw MeshingError("Poisson reconstruction gave no surface");

  start = Clock::now();
  if (options.watertight) {
    // A print needs one closed shell: Poisson's surface is closed, islands go.
    result.dropped_components = DropSmallComponents(poisson.get(), 1.0);
  } else {
    std::vector<bool> drop(poisson->vertices_.size(), false);
    const open3d::geometry::KDTreeFlann tree(*points);
    std::vector<int> index(1);
    std::vector<double> distance2(1);
    const double max_distance2 = options.trim_distance_mm * options.trim_distance_mm;
    double density_threshold = -std::numeric_limits<double>::infinity();
    if (options.trim_density_quantile > 0) {
      std::vector<double> sorted = densities;
      const size_t k = static_cast<size_t>(options.trim_density_quantile * sorted.size());
      std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
      density_threshold = sorted[k];
    }
    for (size_t v = 0; v < poisson->vertices_.size(); ++v) {
      if (densities[v] < density_threshold) {
        drop[v] = true;
        ++result.trimmed_low_density;
      } else if (tree.SearchKNN(poisson->vertices_[v], 1, index, distance2) < 1 ||
                 distance2[0] > max_distance2) {
        drop[v] = true;
        ++result.trimmed_far;
      }
    }
    poisson->RemoveVerticesByMask(drop);
    result.dropped_components =
        DropSmallComponents(poisson.get(), options.min_component_area_share);
  }
  if (poisson->triangles_.empty()) {
    throw MeshingError("no surface left after trimming what the points do not support");
  }
  poisson->ComputeVertexNormals();
  result.trim_s = SecondsSince(start);

  result.mesh = FromOpen3d(*poisson);
  result.stats = ComputeStats(result.mesh);
  result.holes = FindHoles(result.mesh);
  if (options.watertight && !result.stats.watertight) {
    result.warnings.push_back("--watertight: Poisson's surface is not closed (" +
                              std::to_string(result.holes.count()) + " holes)");
  }
  return result;
}

HoleReport FindHoles(const TriangleMesh& mesh) {
  // Count each undirected edge; a boundary edge is used by one triangle only and is
  // walked in its triangle's direction, so a hole's loop is followed one way round.
  std::map<std::pair<int, int>, int> uses;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  }
  std::unordered_multimap<int, int> next;  // boundary edge a -> b
  int boundary_edges = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if (uses[{std::min(a, b), std::max(a, b)}] == 1) {
        next.emplace(a, b);
        ++boundary_edges;
      }
    }
  }
  HoleReport report;
  int on_loops = 0;
  // Start vertices in a fixed order so the report does not depend on hashing.
  std::vector<int> starts;
  for (const auto& [a, b] : next) starts.push_back(a);
  std::sort(starts.begin(), starts.end());
  for (int start : starts) {
    auto first = next.find(start);
    if (first == next.end()) continue;
    Hole hole;
    int current = start;
    std::vector<int> loop;
    bool closed = false;
    while (true) {
      auto edge = next.find(current);
      if (edge == next.end()) break;
      const int to = edge->second;
      next.erase(edge);
      hole.perimeter_mm += (mesh.vertices[to] - mesh.vertices[current]).norm();
      hole.centroid += mesh.vertices[current];
      loop.push_back(current);
      current = to;
      if (current == start) {
        closed = true;
        break;
      }
    }
    if (closed) {
      hole.edges = static_cast<int>(loop.size());
      hole.centroid /= static_cast<double>(loop.size());
      on_loops += hole.edges;
      report.holes.push_back(hole);
    }
  }
  report.open_boundary_edges = boundary_edges - on_loops;
  std::sort(report.holes.begin(), report.holes.end(),
            [](const Hole& a, const Hole& b) { return a.perimeter_mm > b.perimeter_mm; });
  return report;
}

MeshStats ComputeStats(const TriangleMesh& mesh) {
  MeshStats stats;
  stats.vertices = static_cast<int>(mesh.vertices.size());
  stats.triangles = static_cast<int>(mesh.triangles.size());
  if (mesh.triangles.empty()) return stats;
  open3d::geometry::TriangleMesh o3d = ToOpen3d(mesh);
  stats.area_mm2 = o3d.GetSurfaceArea();
  stats.edge_manifold = o3d.IsEdgeManifold(/*allow_boundary_edges=*/true);
  // Open3D's IsWatertight (and GetVolume, which calls it) tests self-intersection over all
  // triangle pairs: minutes on a body mesh. Closed = every edge in two triangles and every
  // vertex a single fan.
  const HoleReport holes = FindHoles(mesh);
  stats.watertight = stats.edge_manifold && holes.count() == 0 && holes.open_boundary_edges == 0 &&
                     o3d.IsVertexManifold();
  if (stats.watertight) {
    double six_volume = 0.0;  // divergence theorem: signed tetrahedra from the origin
    for (const Eigen::Vector3i& t : mesh.triangles) {
      six_volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]]));
    }
    stats.volume_mm3 = std::abs(six_volume) / 6.0;
  }
  const auto clusters = o3d.ClusterConnectedTriangles();
  stats.components = static_cast<int>(std::get<1>(clusters).size());
  for (const Eigen::Vector3d& v : mesh.vertices) stats.bounds.extend(v);
  double edge_sum = 0.0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      edge_sum += (mesh.vertices[t[k]] - mesh.vertices[t[(k + 1) % 3]]).norm();
    }
  }
  stats.mean_edge_mm = edge_sum / (3.0 * static_cast<double>(mesh.triangles.size()));
  return stats;
}

nlohmann::json SummaryJson(const MeshingResult& r) {
  auto vector = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  nlohmann::json holes = nlohmann::json::array();
  for (const auto& hole : r.holes.holes) {
    holes.push_back({{"perimeter_mm", hole.perimeter_mm},
                     {"edges", hole.edges},
                     {"centroid_mm", vector(hole.centroid)}});
  }
  return {
      {"input_points", r.input_points},
      {"downsampled_points", r.downsampled_points},
      {"poisson_depth", r.depth},
      {"poisson_cell_mm", r.cell_mm},
      {"poisson_vertices", r.poisson_vertices},
      {"trimmed",
       {{"far_vertices", r.trimmed_far},
        {"low_density_vertices", r.trimmed_low_density},
        {"small_components", r.dropped_components}}},
      {"vertices", r.stats.vertices},
      {"triangles", r.stats.triangles},
      {"components", r.stats.components},
      {"area_mm2", r.stats.area_mm2},
      {"volume_mm3", r.stats.watertight ? nlohmann::json(r.stats.volume_mm3) : nlohmann::json()},
      {"watertight", r.stats.watertight},
      {"edge_manifold", r.stats.edge_manifold},
      {"mean_edge_mm", r.stats.mean_edge_mm},
      {"bounds_mm", {{"min", vector(r.stats.bounds.min())}, {"max", vector(r.stats.bounds.max())}}},
      {"holes",
       {{"count", r.holes.count()},
        {"largest_perimeter_mm", r.holes.largest_perimeter_mm()},
        {"open_boundary_edges", r.holes.open_boundary_edges},
        {"loops", holes}}},
      {"timings_s", {{"downsample", r.downsample_s}, {"poisson", r.poisson_s}, {"trim", r.trim_s}}},
      {"warnings", r.warnings}};
}

std::string Open3dVersion() {
  return std::to_string(OPEN3D_VERSION_MAJOR) + "." + std::to_string(OPEN3D_VERSION_MINOR) + "." +
         std::to_string(OPEN3D_VERSION_PATCH);
}

}  // namespace mirrorscan::meshing

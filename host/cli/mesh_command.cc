#include "host/cli/mesh_command.h"

#include <cstdio>
#include <memory>
#include <sstream>

#include "host/cli/exit_status.h"
#include "host/cli/progress.h"

namespace mirrorscan::cli {
namespace {

namespace fs = std::filesystem;

struct MeshCommandOptions {
  std::string points;
  std::string out;
  std::string formats = "ply";
  meshing::MeshingOptions meshing;
  bool json = false;
};

nlohmann::json Vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

void Run(const MeshCommandOptions& o) {
  const std::vector<std::string> formats = ParseFormats(o.formats);
  try {
    o.meshing.Validate();
  } catch (const std::invalid_argument& e) {
    throw CommandExit(kExitUsage, e.what());
  }
  if (fs::path(o.out).extension() != ".ply") {
    throw CommandExit(kExitUsage,
                      "--out " + o.out + ": must end in .ply (--formats adds .obj/.stl)");
  }
  Progress progress("mesh");
  progress.Stage("reading " + o.points);
  meshing::OrientedCloud cloud;
  try {
    cloud = meshing::ReadOrientedCloud(o.points);
  } catch (const meshing::MeshingError& e) {
    throw CommandExit(kExitUsage, e.what());
  }
  progress.Stage("Poisson surface");
  meshing::MeshingResult result;
  try {
    result = meshing::MeshCloud(cloud, o.meshing);
  } catch (const meshing::MeshingError& e) {
    throw CommandExit(kExitFailure, o.points + ": no usable mesh: " + e.what());
  }
  progress.Stage("writing");
  const auto written = WriteMeshFormats(result.mesh, o.out, formats);
  progress.Done();
  nlohmann::json summary = MeshingJson(result);
  summary["files"] = nlohmann::json::array();
  for (const auto& file : written) summary["files"].push_back(file.string());
  if (o.json) {
    std::printf("%s\n", summary.dump(2).c_str());
    return;
  }
  for (const auto& warning : result.warnings) std::printf("warning: %s\n", warning.c_str());
  std::printf(
      "%d points (%d after downsampling) -> %d vertices, %d triangles; depth %d (%.2f mm cells)\n",
      result.input_points, result.downsampled_points, result.stats.vertices, result.stats.triangles,
      result.depth, result.cell_mm);
  std::printf("area %.0f cm2, %d component(s), %d hole(s), largest %.0f mm round%s\n",
              result.stats.area_mm2 / 100.0, result.stats.components, result.holes.count(),
              result.holes.largest_perimeter_mm(), result.stats.watertight ? ", watertight" : "");
  for (const auto& file : written) std::printf("%s\n", file.string().c_str());
}

}  // namespace

void AddMeshingFlags(CLI::App* command, meshing::MeshingOptions* options) {
  command
      ->add_option("--voxel", options->voxel_mm,
                   "downsampling voxel in mm before Poisson (0: none)")
      ->capture_default_str();
  command
      ->add_option("--cell", options->cell_mm,
                   "finest Poisson cell in mm (the octree depth follows)")
      ->capture_default_str();
  command->add_option("--depth", options->depth, "Poisson octree depth (overrides --cell)");
  command->add_option("--threads", options->threads, "Poisson threads")->capture_default_str();
  command
      ->add_option("--trim-distance", options->trim_distance_mm,
                   "drop surface further than this (mm) from every point")
      ->capture_default_str();
  command->add_flag("--watertight", options->watertight,
                    "keep Poisson's closed surface (for printing); no trimming");
}

std::vector<std::string> ParseFormats(const std::string& formats) {
  std::vector<std::string> out;
  std::stringstream in(formats);
  std::string format;
  while (std::getline(in, format, ',')) {
    if (format != "ply" && format != "obj" && format != "stl") {
      throw CommandExit(kExitUsage, "--formats: \"" + format + "\" is not one of ply, obj, stl");
    }
    if (std::find(out.begin(), out.end(), format) == out.end()) out.push_back(format);
  }
  if (std::find(out.begin(), out.end(), "ply") == out.end()) out.insert(out.begin(), "ply");
  return out;
}

std::vector<fs::path> WriteMeshFormats(const meshing::Mesh& mesh, const fs::path& ply_path,
                                       const std::vector<std::string>& formats) {
  std::vector<fs::path> written;
  for (const std::string& format : formats) {
    fs::path file = ply_path;
    file.replace_extension("." + format);
    meshing::WriteMesh(mesh, file);
    written.push_back(file);
  }
  return written;
}

nlohmann::json MeshingJson(const meshing::MeshingResult& r) {
  nlohmann::json holes = nlohmann::json::array();
  for (const auto& hole : r.holes.holes) {
    holes.push_back({{"perimeter_mm", hole.perimeter_mm},
                     {"edges", hole.edges},
                     {"centroid_mm", Vector(hole.centroid)}});
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
      {"bounds_mm", {{"min", Vector(r.stats.bounds.min())}, {"max", Vector(r.stats.bounds.max())}}},
      {"holes",
       {{"count", r.holes.count()},
        {"largest_perimeter_mm", r.holes.largest_perimeter_mm()},
        {"open_boundary_edges", r.holes.open_boundary_edges},
        {"loops", holes}}},
      {"timings_s", {{"downsample", r.downsample_s}, {"poisson", r.poisson_s}, {"trim", r.trim_s}}},
      {"warnings", r.warnings}};
}

void AddMeshCommand(CLI::App& app) {
  auto options = std::make_shared<MeshCommandOptions>();
  auto* cmd = app.add_subcommand("mesh", "Poisson surface of an oriented point cloud (PLY)");
  cmd->add_option("points", options->points, "point cloud with normals (PLY)")->required();
  cmd->add_option("--out", options->out, "mesh file (.ply; --formats adds others beside it)")
      ->required();
  cmd->add_option("--formats", options->formats, "comma-separated: ply, obj, stl")
      ->capture_default_str();
  AddMeshingFlags(cmd, &options->meshing);
  cmd->add_flag("--json", options->json, "print the summary as JSON");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

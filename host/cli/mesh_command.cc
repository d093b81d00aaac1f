#include "host/cli/mesh_command.h"

#include <cstdio>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/mesh/cloud_io.h"
#include "host/cli/exit_status.h"
#include "host/cli/progress.h"
#include "host/pipeline/pipeline.h"

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
  PointCloud cloud;
  try {
    cloud = ReadPointCloud(o.points, /*require_normals=*/true);
  } catch (const MeshIoError& e) {
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
  const auto written = pipeline::WriteMeshFormats(result.mesh, o.out, formats);
  progress.Done();
  nlohmann::json summary = meshing::SummaryJson(result);
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
  std::vector<std::string> list;
  std::stringstream in(formats);
  for (std::string format; std::getline(in, format, ',');) list.push_back(format);
  try {
    return pipeline::CheckMeshFormats(list);
  } catch (const pipeline::InputError& e) {
    throw CommandExit(kExitUsage, std::string("--") + e.what());
  }
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

#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "host/meshing/meshing.h"

namespace mirrorscan::cli {

// `mirrorscan mesh points.ply --out mesh.ply`: a Poisson surface of an oriented cloud.
void AddMeshCommand(CLI::App& app);

// The meshing flags `mesh` and `process` share (--voxel, --cell, --depth, --threads,
// --trim-distance, --watertight).
void AddMeshingFlags(CLI::App* command, meshing::MeshingOptions* options);
// --formats: "ply", "obj", "stl" in any comma-separated combination; throws CommandExit
// (usage) on anything else.
std::vector<std::string> ParseFormats(const std::string& formats);

}  // namespace mirrorscan::cli

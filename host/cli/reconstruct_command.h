#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan reconstruct SCAN.mscan --calibration C.json --out points.ply [--json]`: the
// scan's peaks to a point cloud (host/reconstruction).
void AddReconstructCommand(CLI::App& app);

}  // namespace mirrorscan::cli

#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan process SCAN.mscan --calibration C.json --out DIR`: reconstruction, mesh,
// previews and summary.json in DIR, as a stateless batch job (docs/meshing.md).
void AddProcessCommand(CLI::App& app);

}  // namespace mirrorscan::cli

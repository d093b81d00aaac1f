#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan measure MESH --out m.json [--csv m.csv] [--girth-at Z,...] [--preview P.png]
// [--json]`: body measurements from a mesh (docs/measurement.md).
void AddMeasureCommand(CLI::App& app);

}  // namespace mirrorscan::cli

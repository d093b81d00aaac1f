#pragma once

#include <filesystem>

#include <CLI/CLI.hpp>

#include "host/pipeline/pipeline.h"

namespace mirrorscan::cli {

// `mirrorscan process SCAN.mscan --calibration C.json --out DIR`: reconstruction, mesh,
// previews and summary.json in DIR, as a stateless batch job (docs/meshing.md).
void AddProcessCommand(CLI::App& app);

// pipeline::Process with its progress on stderr. Its errors end as CommandExit with the
// documented status (docs/meshing.md: 2 bad input, 1 no usable result, 3 upload refused),
// a failed run's upload trouble printed as a warning first.
pipeline::ProcessResult RunProcess(const std::filesystem::path& archive,
                                   const std::filesystem::path& calibration,
                                   const std::filesystem::path& board,
                                   const std::filesystem::path& out,
                                   pipeline::ProcessOptions options);

}  // namespace mirrorscan::cli

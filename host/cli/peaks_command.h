#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan peaks IMAGE...`: the on-device peak extractor run on image files.
void AddPeaksCommand(CLI::App& app);

}  // namespace mirrorscan::cli

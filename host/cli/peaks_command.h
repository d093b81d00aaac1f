#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "common/peaks/peaks.h"

namespace mirrorscan::cli {

// Extractor parameters from a board.json's "peaks" object; defaults when it has none.
PeakParams PeakParamsFromBoard(const std::string& board_json);

// `mirrorscan peaks IMAGE...`: the on-device peak extractor run on image files.
void AddPeaksCommand(CLI::App& app);

}  // namespace mirrorscan::cli

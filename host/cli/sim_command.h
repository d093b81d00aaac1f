#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan sim render|scan`: the virtual cabinet, offline.
void AddSimCommands(CLI::App& app);

}  // namespace mirrorscan::cli

#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan device status|list|scan|fetch|delete|calibration get|put|capture|discover`:
// the device API from the command line (docs/cli-device.md).
void AddDeviceCommands(CLI::App& app);

}  // namespace mirrorscan::cli

#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan calibrate-lasers SCAN.mscan --calibration C.json --out lasers.json`: every
// frame's laser planes from the lines on the panels beside the mirrors.
void AddCalibrateLasersCommand(CLI::App& app);

}  // namespace mirrorscan::cli

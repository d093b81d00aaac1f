#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan calibrate`: the cabinet's calibration from one target image per camera, or
// with --verify, a check of a stored calibration against fresh images.
void AddCalibrateCommand(CLI::App& app);

}  // namespace mirrorscan::cli

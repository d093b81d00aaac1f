#pragma once

#include <CLI/CLI.hpp>

namespace mirrorscan::cli {

// `mirrorscan calibrate-intrinsics --chessboard 9x6 --square MM IMAGE... --out FILE`
// (or --charuco): a lens calibrated from photographs of a flat board.
void AddCalibrateIntrinsicsCommand(CLI::App& app);

}  // namespace mirrorscan::cli

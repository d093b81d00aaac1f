#pragma once
// The virtual board's board.json for the tests that run mirrorscand.

#include <filesystem>

namespace mirrorscan::test_support {

// Writes DIR/board.json: the shipped virtual board over the mannequin, sweeping from 200 mm
// to `sweep_end_mm`, and with `replay` both cameras replaying one 160 x 120 frame of a
// horizontal stripe (DIR/frames0, DIR/frames1) instead of the renderer, so a sweep costs no
// rendering. Returns the file's path.
std::filesystem::path WriteVirtualBoard(const std::filesystem::path& dir, double sweep_end_mm,
                                        bool replay);

}  // namespace mirrorscan::test_support

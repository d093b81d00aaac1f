#pragma once

#include "firmware/board/simulator.h"

namespace mirrorscan::board {

// The simulator as this program links it, for mirrorscand: the host build's has the drive
// simulator and the virtual cabinet's renderer (linked_simulator.cc); the firmware-only
// build's, the board's, has neither (no_simulator.cc), so it refuses a board with virtual
// drive or cameras in one error instead of faking them.
Simulator LinkedSimulator();

}  // namespace mirrorscan::board

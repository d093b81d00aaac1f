// The firmware-only build (the board's) links no simulator: a board asking for a virtual
// drive or virtual cameras fails in MakeBoardDevices with one clear error instead of using
// anything else. Virtual GPIO lines (firmware/hal/virtual) are not the simulator and stay.
#include "firmware/board/virtual/linked_simulator.h"

namespace mirrorscan::board {

Simulator LinkedSimulator() { return {}; }

}  // namespace mirrorscan::board

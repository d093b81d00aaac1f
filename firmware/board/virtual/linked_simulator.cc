// The host build's simulator: the drive simulator and the virtual cabinet's renderer.
#include "firmware/board/virtual/linked_simulator.h"

#include <memory>

#include "firmware/board/virtual/rendered_cabinet.h"
#include "firmware/board/virtual/simulated_drive.h"

namespace mirrorscan::board {

Simulator LinkedSimulator() {
  return {[] { return std::make_unique<SimulatedModbusDrive>(); }, OpenRenderedCabinet};
}

}  // namespace mirrorscan::board

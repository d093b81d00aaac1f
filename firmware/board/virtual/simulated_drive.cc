#include "firmware/board/virtual/simulated_drive.h"

#include <spdlog/spdlog.h>

namespace mirrorscan::board {

SimulatedModbusDrive::SimulatedModbusDrive() : sim_(virtual_cabinet::DriveSim::ServeTcp({})) {
  if (!sim_->realtime_error().empty()) {
    spdlog::warn("virtual drive: {}; on a busy machine it may answer late", sim_->realtime_error());
  }
}

double SimulatedModbusDrive::TruePositionMm(int64_t steady_ns) {
  return sim_->State().model.PositionAt(steady_ns);
}

}  // namespace mirrorscan::board

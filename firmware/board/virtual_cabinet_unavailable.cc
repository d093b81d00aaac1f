// The firmware-only build (the board's) has no renderer: a board asking for virtual
// cameras fails here with one clear error instead of using anything else.
#include "firmware/board/devices.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::board {

std::unique_ptr<VirtualCabinet> OpenVirtualCabinet(const std::filesystem::path& scene,
                                                   double /*sweep_start_mm*/) {
  throw hal::HardwareError(hal::HardwareError::Kind::kInvalidArgument,
                           "virtual cameras (scene " + scene.string() +
                               ") need the virtual cabinet's renderer, which this "
                               "firmware-only build does not have; use the host build or "
                               "replay cameras");
}

}  // namespace mirrorscan::board

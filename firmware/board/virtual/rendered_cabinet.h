#pragma once

#include <filesystem>
#include <memory>

#include "firmware/board/simulator.h"

namespace mirrorscan::board {

// The virtual cabinet's renderer (Embree, OpenCV: host build only) behind a board's
// "virtual" cameras: loads `scene` and renders it (Simulator::open_cabinet).
std::unique_ptr<VirtualCabinet> OpenRenderedCabinet(const std::filesystem::path& scene,
                                                    double sweep_start_mm);

}  // namespace mirrorscan::board

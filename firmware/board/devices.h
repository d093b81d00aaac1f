#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "boards/virtual/drive_sim/drive_sim.h"
#include "firmware/board/board_config.h"
#include "firmware/hal/camera.h"
#include "firmware/hal/gpio_factory.h"
#include "firmware/hal/slide_drive.h"
#include "firmware/hal/virtual/virtual_gpio_line.h"
#include "firmware/hal/virtual/virtual_monostable.h"

namespace mirrorscan::board {

// The virtual cabinet's renderer behind a board's "virtual" cameras.
class VirtualCabinet {
 public:
  virtual ~VirtualCabinet() = default;
  // A camera rendering scene camera `scene_camera`; each frame at the slide position
  // slide_mm(its exposure time, steady ns) (mm along the slide) with lasers_on(). Throws
  // HardwareError.
  virtual std::unique_ptr<hal::Camera> MakeCamera(int scene_camera,
                                                  std::function<double(int64_t)> slide_mm,
                                                  std::function<bool()> lasers_on) = 0;
};

// Loads `scene` and its renderer; at slide position `sweep_start_mm` the scene's laser 0
// is where the scene puts it at t = 0. Only the host build has the renderer (Embree,
// OpenCV): the firmware-only build links a version that throws HardwareError
// kInvalidArgument saying so.
std::unique_ptr<VirtualCabinet> OpenVirtualCabinet(const std::filesystem::path& scene,
                                                   double sweep_start_mm);

struct DeviceOptions {
  // Replaces board.json's virtual.scene (virtual boards only), e.g. the calibration
  // target scene for calibration captures.
  std::filesystem::path scene;
  // Virtual boards: mirror the laser interlock's state here (VirtualMonostable).
  std::optional<std::filesystem::path> interlock_state_file;
  // Virtual boards: mirror the output lines' levels here (VirtualLineStates).
  std::optional<std::filesystem::path> line_state_file;
};

// Every device of a board, built from its BoardConfig. Members are destroyed cameras
// first and the simulated drive last.
struct BoardDevices {
  std::unique_ptr<virtual_cabinet::DriveSim> drive_sim;  // drive.backend "virtual"
  std::unique_ptr<hal::SlideDrive> drive;
  hal::GpioDevices gpio;
  // gpio.backend "virtual": the lines, for the daemon's button hook and for tests.
  std::vector<hal::VirtualGpioLine*> virtual_lasers;
  hal::VirtualGpioLine* virtual_button = nullptr;
  hal::VirtualMonostable* virtual_interlock = nullptr;  // gates the virtual lasers' light
  bool button_active_low = false;
  std::unique_ptr<VirtualCabinet> cabinet;
  std::vector<std::unique_ptr<hal::Camera>> cameras;  // board order, configured
};

// Builds and configures every device. A backend that cannot start is a HardwareError
// naming the device: never a silent fallback to a simulation. Drive "virtual" is the
// in-process DriveSim served over loopback TCP and driven through the real
// ModbusSlideDrive, so the Modbus path is exercised. Virtual cameras need the virtual
// drive and virtual GPIO (they render the simulated slide and laser lines).
BoardDevices MakeBoardDevices(const BoardConfig& config, const DeviceOptions& options = {});

}  // namespace mirrorscan::board

#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "firmware/board/board_config.h"
#include "firmware/board/gpio_factory.h"
#include "firmware/board/simulator.h"
#include "firmware/hal/camera.h"
#include "firmware/hal/slide_drive.h"
#include "firmware/hal/virtual/virtual_gpio_line.h"
#include "firmware/hal/virtual/virtual_monostable.h"

namespace mirrorscan::board {

struct DeviceOptions {
  // What a board's "virtual" drive and cameras are made of (firmware/board/virtual's
  // LinkedSimulator() in mirrorscand). Empty: such a board is refused with one error.
  Simulator simulator;
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
  std::unique_ptr<SimulatedDrive> drive_sim;  // drive.backend "virtual"
  std::unique_ptr<hal::SlideDrive> drive;
  GpioDevices gpio;
  // gpio.backend "virtual": the lines, for the daemon's button hook and for tests.
  std::vector<hal::VirtualGpioLine*> virtual_lasers;
  hal::VirtualGpioLine* virtual_button = nullptr;
  hal::VirtualMonostable* virtual_interlock = nullptr;  // gates the virtual lasers' light
  bool button_active_low = false;
  std::unique_ptr<VirtualCabinet> cabinet;
  std::vector<std::unique_ptr<hal::Camera>> cameras;  // board order, configured
};

// Builds and configures every device. A backend that cannot start is a HardwareError
// naming the device: never a silent fallback to a simulation. Drive "virtual" is
// options.simulator's drive, served over loopback TCP and driven through the real
// ModbusSlideDrive, so the Modbus path is exercised. Virtual cameras need the virtual
// drive and virtual GPIO (they render the simulated slide and laser lines). A board whose
// virtual drive or cameras options.simulator cannot make is one HardwareError
// kInvalidArgument naming them, before any device starts.
BoardDevices MakeBoardDevices(const BoardConfig& config, const DeviceOptions& options = {});

}  // namespace mirrorscan::board

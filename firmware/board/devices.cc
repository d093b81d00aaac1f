#include "firmware/board/devices.h"

#include <algorithm>
#include <string>
#include <utility>

#include "firmware/hal/hardware_error.h"
#include "firmware/hal/libcamera/libcamera_loader.h"
#include "firmware/hal/modbus/modbus_slide_drive.h"
#include "firmware/hal/replay/replay_camera.h"

namespace mirrorscan::board {
namespace {

using hal::HardwareError;

std::unique_ptr<hal::SlideDrive> MakeDrive(const BoardConfig& config, const DeviceOptions& options,
                                           BoardDevices& devices) {
  if (config.drive.backend == BoardDrive::Backend::kModbus) {
    return std::make_unique<hal::ModbusSlideDrive>(config.drive.modbus);
  }
  devices.drive_sim = options.simulator.serve_drive();
  // Both ends default to the same register map (common/modbus/register_map.h).
  hal::ModbusDriveConfig modbus;
  modbus.host = "127.0.0.1";
  modbus.port = devices.drive_sim->port();
  return std::make_unique<hal::ModbusSlideDrive>(modbus);
}

// What the board asks of the simulator that `simulator` does not have, e.g.
// `drive.backend "virtual", cameras upper, lower "virtual"`; "" when nothing is missing.
std::string MissingSimulatorParts(const BoardConfig& config, const Simulator& simulator) {
  std::string missing;
  if (config.drive.backend == BoardDrive::Backend::kVirtual && !simulator.serve_drive) {
    missing = "drive.backend \"virtual\"";
  }
  std::string cameras;
  for (const BoardCamera& camera : config.cameras) {
    if (camera.backend != CameraBackend::kVirtual || simulator.open_cabinet) continue;
    cameras += (cameras.empty() ? "" : ", ") + camera.name;
  }
  if (!cameras.empty()) {
    missing += (missing.empty() ? "cameras " : ", cameras ") + cameras + " \"virtual\"";
  }
  return missing;
}

std::unique_ptr<hal::Camera> MakeCamera(const BoardConfig& config, const BoardCamera& camera,
                                        const DeviceOptions& options, BoardDevices& devices) {
  switch (camera.backend) {
    case CameraBackend::kLibcamera:
      // The module is dlopen'ed here and only here (docs/cameras.md).
      return hal::OpenLibcameraCamera(camera.id);
    case CameraBackend::kReplay:
      // A recording loops: a sweep usually outlasts it.
      return std::make_unique<hal::ReplayCamera>(hal::ReplayOptions{camera.path, true});
    case CameraBackend::kVirtual:
      break;
  }
  if (!devices.drive_sim || devices.virtual_lasers.empty()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera " + camera.name +
                            ": a virtual camera needs drive.backend and gpio.backend \"virtual\"");
  }
  if (!devices.cabinet) {
    const std::filesystem::path scene =
        options.scene.empty() ? config.virtual_scene : options.scene;
    devices.cabinet = options.simulator.open_cabinet(scene, config.scan.sweep_start_mm);
  }
  SimulatedDrive* sim = devices.drive_sim.get();
  std::vector<std::pair<hal::VirtualGpioLine*, bool>> lasers;
  for (size_t i = 0; i < devices.virtual_lasers.size(); ++i) {
    lasers.emplace_back(devices.virtual_lasers[i], config.gpio.lasers[i].active_low);
  }
  // The scene sees the true slide (the simulation's state, not the Modbus readback) where
  // it was at the frame's exposure: the camera thread renders later, by up to a frame
  // period when it runs late, and the slide has moved on by then.
  const auto slide_at = [sim](int64_t exposure_ns) { return sim->TruePositionMm(exposure_ns); };
  // A laser emits while its line is driven and the interlock's pulse runs.
  const hal::VirtualMonostable* interlock = devices.virtual_interlock;
  return devices.cabinet->MakeCamera(camera.scene_camera, slide_at, [lasers, interlock] {
    if (interlock != nullptr && !interlock->OutputHigh(hal::SteadyNowNs())) return false;
    return std::any_of(lasers.begin(), lasers.end(), [](const auto& line) {
      return hal::ActiveLevelLine::ToActive(line.first->driven(), line.second);
    });
  });
}

}  // namespace

BoardDevices MakeBoardDevices(const BoardConfig& config, const DeviceOptions& options) {
  const bool any_virtual_camera =
      std::any_of(config.cameras.begin(), config.cameras.end(),
                  [](const BoardCamera& c) { return c.backend == CameraBackend::kVirtual; });
  if (!options.scene.empty() && !any_virtual_camera) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "--scene is for boards with virtual cameras only");
  }
  const std::string missing = MissingSimulatorParts(config, options.simulator);
  if (!missing.empty()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "board " + config.board + ": " + missing +
                            " need the virtual cabinet's simulator, which this program does not "
                            "link (the firmware-only build has none); use the host build's "
                            "mirrorscand, or a board with modbus drive and libcamera or replay "
                            "cameras");
  }
  BoardDevices devices;
  devices.drive = MakeDrive(config, options, devices);

  GpioLines lines = MakeGpioLines(config.gpio, config.gpio.backend, options.interlock_state_file,
                                  options.line_state_file);
  if (config.gpio.backend == hal::GpioBackend::kVirtual) {
    devices.virtual_interlock = dynamic_cast<hal::VirtualMonostable*>(lines.interlock.line.get());
    for (auto& laser : lines.lasers) {
      devices.virtual_lasers.push_back(dynamic_cast<hal::VirtualGpioLine*>(laser.line.get()));
    }
    devices.virtual_button = dynamic_cast<hal::VirtualGpioLine*>(lines.button.line.get());
    devices.button_active_low = config.gpio.button.active_low;
  }
  devices.gpio = MakeGpioDevices(config.gpio, std::move(lines));

  for (const BoardCamera& camera : config.cameras) {
    std::unique_ptr<hal::Camera> made = MakeCamera(config, camera, options, devices);
    made->Configure(camera.config);
    devices.cameras.push_back(std::move(made));
  }
  return devices;
}

}  // namespace mirrorscan::board

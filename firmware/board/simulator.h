#pragma once
// The seam between the firmware and the virtual cabinet's simulator (boards/virtual): what a
// board's "virtual" drive and cameras need from it. firmware/board/virtual/ implements it;
// nothing else in the firmware includes boards/virtual, so a program that does not link
// that folder (the board's mirrorscand) carries no simulator (docs/firmware.md).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>

#include "firmware/hal/camera.h"

namespace mirrorscan::board {

// drive.backend "virtual": a simulated slide drive serving Modbus TCP on loopback, which
// the firmware drives through its real ModbusSlideDrive (default register map).
class SimulatedDrive {
 public:
  virtual ~SimulatedDrive() = default;
  virtual int port() const = 0;  // on 127.0.0.1
  // The simulation's true slide position (mm) at steady time `steady_ns`, not the Modbus
  // readback: what the virtual cameras see.
  virtual double TruePositionMm(int64_t steady_ns) = 0;
  // Fault injection (mirrorscand's test hooks).
  virtual void InjectFault(int code) = 0;
  virtual void SetResponding(bool responding) = 0;
};

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

// The parts of the simulator a program links; an empty factory is a part it does not have,
// and a board that needs it is refused (never a silent fallback).
struct Simulator {
  std::function<std::unique_ptr<SimulatedDrive>()> serve_drive;
  // Loads `scene` and its renderer; at slide position `sweep_start_mm` the scene's laser 0
  // is where the scene puts it at t = 0.
  std::function<std::unique_ptr<VirtualCabinet>(const std::filesystem::path& scene,
                                                double sweep_start_mm)>
      open_cabinet;
};

}  // namespace mirrorscan::board

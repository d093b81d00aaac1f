#pragma once

#include <memory>

#include "boards/virtual/drive_sim/drive_sim.h"
#include "firmware/board/simulator.h"

namespace mirrorscan::board {

// drive.backend "virtual" as the drive simulator (boards/virtual/drive_sim) serving Modbus
// TCP on loopback. It needs only libmodbus, so it builds for the board too: the firmware's
// tests use it under qemu, the board's mirrorscand does not link it.
class SimulatedModbusDrive final : public SimulatedDrive {
 public:
  // Serves on an ephemeral port; warns when its thread could not be made to run first.
  SimulatedModbusDrive();

  int port() const override { return sim_->port(); }
  double TruePositionMm(int64_t steady_ns) override;
  void InjectFault(int code) override { sim_->InjectFault(code); }
  void SetResponding(bool responding) override { sim_->SetResponding(responding); }

  // The simulator itself, for tests that read its state.
  virtual_cabinet::DriveSim& sim() { return *sim_; }

 private:
  std::unique_ptr<virtual_cabinet::DriveSim> sim_;
};

}  // namespace mirrorscan::board

#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "boards/virtual/drive_sim/drive_model.h"
#include "common/modbus/register_map.h"

typedef struct _modbus modbus_t;                    // NOLINT: libmodbus's own types
typedef struct _modbus_mapping_t modbus_mapping_t;  // NOLINT

namespace mirrorscan::virtual_cabinet {

struct DriveSimConfig {
  // The map it serves: the firmware's (board.json's drive.registers); by default that of
  // docs/slide-drive.md.
  ModbusRegisterMap map;
  DriveModelConfig model;
  int slave_id = 1;
};

struct DriveSimState {
  DriveModelState model;
  uint64_t requests = 0;  // well-formed requests received (answered or not)
};

// A simulated slide drive that is a real libmodbus server, running in its own thread:
// over TCP on 127.0.0.1 (ephemeral port) or over RTU on a pseudo-terminal pair whose
// slave side a client opens like a serial port. One client at a time; a new TCP
// connection replaces the old one. Every request first advances the motion model to now
// (steady clock), then is answered from the register map, then commands written by it
// take effect, all under one lock, so State() after a client's call returns sees its
// effect.
class DriveSim {
 public:
  static std::unique_ptr<DriveSim> ServeTcp(const DriveSimConfig& config);
  static std::unique_ptr<DriveSim> ServeRtu(const DriveSimConfig& config);
  ~DriveSim();
  DriveSim(const DriveSim&) = delete;
  DriveSim& operator=(const DriveSim&) = delete;

  int port() const { return port_; }                     // TCP
  const std::string& device() const { return device_; }  // RTU: the pty path to open
  // Why its thread could not be made to run first (RunThreadFirst), or "": hardware
  // answers whatever the host is doing, so the simulated drive should too.
  const std::string& realtime_error() const { return realtime_error_; }

  DriveSimState State();  // advanced to now

  // Fault injection.
  void InjectFault(int code);           // fault bit + code, the slide stops
  void SetResponding(bool responding);  // false: requests are read and never answered
  void DropConnection();                // TCP: closes the client's connection (returns after)

 private:
  explicit DriveSim(const DriveSimConfig& config);
  void Run();
  void Serve(uint8_t* request, int length);  // lock held
  void PublishOutputs();                     // model → registers; lock held
  void ApplyInputs(int64_t now_ns);          // registers → model commands; lock held
  void Wake();

  const DriveSimConfig config_;
  std::mutex mutex_;
  DriveModel model_;
  uint64_t requests_ = 0;
  uint16_t applied_speed_counts_ = 0;

  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  bool tcp_ = true;
  int listen_fd_ = -1;     // TCP
  int client_fd_ = -1;     // TCP connection, or the pty master
  int pty_slave_fd_ = -1;  // RTU: held open so the master never sees a hang-up
  int wake_fds_[2] = {-1, -1};
  int port_ = 0;
  std::string device_;
  std::string realtime_error_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> drop_{false};
  std::atomic<bool> responding_{true};
  std::thread thread_;
};

}  // namespace mirrorscan::virtual_cabinet

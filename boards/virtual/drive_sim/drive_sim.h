#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "boards/virtual/drive_sim/drive_model.h"

typedef struct _modbus modbus_t;                    // NOLINT: libmodbus's own types
typedef struct _modbus_mapping_t modbus_mapping_t;  // NOLINT

namespace mirrorscan::virtual_cabinet {

enum class DriveSimTable { kCoils, kHolding, kInput };

// The simulated drive's register map; the same meaning as the firmware's
// ModbusDriveConfig registers (docs/slide-drive.md). Defaults are that document's map.
struct DriveSimRegisterMap {
  DriveSimTable control_table = DriveSimTable::kHolding;  // holding word or coils
  int control_address = 0;
  int enable_bit = 0;
  int home_bit = 1;
  int start_bit = 2;
  int stop_bit = 3;
  int fault_reset_bit = 4;
  DriveSimTable status_table = DriveSimTable::kInput;
  int status_address = 0;
  int enabled_bit = 0;
  int homed_bit = 1;
  int moving_bit = 2;
  int fault_bit = 3;
  DriveSimTable fault_code_table = DriveSimTable::kInput;
  int fault_code_address = 1;
  int speed_address = 1;  // holding, unsigned 16 bit
  double speed_counts_per_mm_s = 10.0;
  int target_address = 2;  // holding, signed 32 bit, position scale and word order
  DriveSimTable position_table = DriveSimTable::kInput;
  int position_address = 2;  // signed 32 bit
  double counts_per_mm = 100.0;
  bool high_word_first = true;
};

struct DriveSimConfig {
  DriveSimRegisterMap map;
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
  std::atomic<bool> stop_{false};
  std::atomic<bool> drop_{false};
  std::atomic<bool> responding_{true};
  std::thread thread_;
};

}  // namespace mirrorscan::virtual_cabinet

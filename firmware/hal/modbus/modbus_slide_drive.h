#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

#include "firmware/hal/modbus/modbus_drive_config.h"
#include "firmware/hal/slide_drive.h"

typedef struct _modbus modbus_t;  // NOLINT: libmodbus's own opaque type

namespace mirrorscan::hal {

// A slide drive on Modbus RTU or TCP (libmodbus), register map from the config.
//
// Every request waits at most response_timeout_s for the answer and is tried
// 1 + retries times; after a timeout or a broken link the connection is closed and
// reopened before the next attempt (so a late answer can never be taken for the next
// one). A Modbus exception from the drive is not retried. A call therefore fails within
// about (1 + retries) * response_timeout_s. Calls are serialised by a mutex; the
// supervisor's Stop() waits for at most the one request in flight.
class ModbusSlideDrive final : public SlideDrive {
 public:
  // Opens the link (a TCP connect or opening the serial device); throws HardwareError
  // if that fails. Nothing is written to the drive.
  explicit ModbusSlideDrive(const ModbusDriveConfig& config);
  ~ModbusSlideDrive() override;
  ModbusSlideDrive(const ModbusSlideDrive&) = delete;
  ModbusSlideDrive& operator=(const ModbusSlideDrive&) = delete;

  void Enable(bool on) override;
  void StartHome() override;
  void SetSpeed(double mm_per_s) override;
  void Start(double target_mm) override;
  void ResetFault() override;
  double Position() override;
  SlideStatus Status() override;

  const ModbusDriveConfig& config() const { return config_; }

 protected:
  void DoStop() override;

 private:
  // Runs one libmodbus request (`request` returns libmodbus's result, -1 on error)
  // with the retry and reconnect policy above. Call with mutex_ held.
  void Transact(const std::string& what, const std::function<int(modbus_t*)>& request);
  void Connect();     // mutex_ held; throws HardwareError
  void Disconnect();  // mutex_ held
  // Writes the enable level plus one command bit (or none when bit < 0).
  void WriteControl(const std::string& what, int command_bit);
  uint16_t ReadRegister(const std::string& what, ModbusTable table, int address);
  void WriteInt32(const std::string& what, int address, int32_t value);
  int32_t ReadInt32(const std::string& what, ModbusTable table, int address);
  std::string Describe() const;  // "modbus tcp 127.0.0.1:1502 slave 1"

  const ModbusDriveConfig config_;
  std::mutex mutex_;
  modbus_t* ctx_ = nullptr;
  bool connected_ = false;
  bool enabled_ = false;  // the enable level we last wrote
};

}  // namespace mirrorscan::hal

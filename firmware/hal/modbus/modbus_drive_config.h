#pragma once

#include <filesystem>
#include <string>

#include "common/config/json_reader.h"
#include "common/modbus/register_map.h"

namespace mirrorscan::hal {

// A Modbus drive link and register map, from board.json's "drive" object
// (docs/slide-drive.md has the keys, an example and the register map).
struct ModbusDriveConfig {
  enum class Transport { kTcp, kRtu };
  Transport transport = Transport::kTcp;
  // TCP.
  std::string host;
  int port = 502;
  // RTU (serial, usually RS-485).
  std::string device;
  int baud = 115200;
  char parity = 'N';  // 'N', 'E' or 'O' as libmodbus wants it
  int data_bits = 8;
  int stop_bits = 1;

  int slave_id = 1;
  double response_timeout_s = 0.1;  // per request
  int retries = 2;                  // further attempts after a failed request

  double max_speed_mm_s = 500.0;
  double travel_min_mm = 0.0;  // soft limits; targets outside are refused before sending
  double travel_max_mm = 2000.0;

  // board.json's drive.registers: shared with the simulated drive (common/modbus).
  ModbusRegisterMap registers;
};

// Parses and validates the "drive" object; errors are ConfigError naming the key
// ("board.json: drive.registers.speed.address: ...").
ModbusDriveConfig ParseModbusDriveConfig(const JsonReader& drive);
// Reads board.json and parses its "drive" object.
ModbusDriveConfig LoadModbusDriveConfig(const std::filesystem::path& board_json);

}  // namespace mirrorscan::hal

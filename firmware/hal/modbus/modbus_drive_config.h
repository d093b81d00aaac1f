#pragma once

#include <filesystem>
#include <string>

#include "common/config/json_reader.h"

namespace mirrorscan::hal {

// Where a value lives on the drive. Coils and holding registers can be written; input
// registers only read.
enum class ModbusTable { kCoils, kHolding, kInput };
// Order of the two 16-bit words of a 32-bit value: the high word at the lower address
// ("high_first", Modbus convention) or the low word there ("low_first").
enum class WordOrder { kHighFirst, kLowFirst };

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

  // Control: one holding register with command bits, or one coil per bit at
  // address + bit. Enable is a level; home/start/stop/fault-reset are commands the drive
  // acts on when their bit is written as 1 (the drive clears them itself).
  struct Control {
    ModbusTable table = ModbusTable::kHolding;
    int address = 0;
    int enable_bit = 0;
    int home_bit = 1;
    int start_bit = 2;
    int stop_bit = 3;
    int fault_reset_bit = 4;
  } control;

  // Status word (holding or input register).
  struct Status {
    ModbusTable table = ModbusTable::kInput;
    int address = 0;
    int enabled_bit = 0;
    int homed_bit = 1;
    int moving_bit = 2;
    int fault_bit = 3;
  } status;

  // Fault code, one 16-bit register (holding or input).
  struct FaultCode {
    ModbusTable table = ModbusTable::kInput;
    int address = 1;
  } fault_code;

  // Target speed, one unsigned 16-bit holding register: counts = mm/s * counts_per_mm_s.
  struct Speed {
    int address = 1;
    double counts_per_mm_s = 10.0;
  } speed;

  // Position readback: signed 32-bit over two registers (holding or input);
  // counts = mm * counts_per_mm.
  struct Position {
    ModbusTable table = ModbusTable::kInput;
    int address = 2;
    double counts_per_mm = 100.0;
    WordOrder word_order = WordOrder::kHighFirst;
  } position;

  // Move target: signed 32-bit over two holding registers, with the position's scale
  // and word order.
  struct Target {
    int address = 2;
  } target;
};

// Parses and validates the "drive" object; errors are ConfigError naming the key
// ("board.json: drive.registers.speed.address: ...").
ModbusDriveConfig ParseModbusDriveConfig(const JsonReader& drive);
// Reads board.json and parses its "drive" object.
ModbusDriveConfig LoadModbusDriveConfig(const std::filesystem::path& board_json);

}  // namespace mirrorscan::hal

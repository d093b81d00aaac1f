// The slide drive's Modbus register map: where each command, readback and value lives on
// the drive (docs/slide-drive.md). One description for both ends of the link: the
// firmware's Modbus backend (firmware/hal/modbus) reads and writes the drive through it,
// and the virtual cabinet's simulated drive (boards/virtual/drive_sim) serves it.
#pragma once

#include "common/config/json_reader.h"

namespace mirrorscan {

// Where a value lives on the drive. Coils and holding registers can be written; input
// registers only read.
enum class ModbusTable { kCoils, kHolding, kInput };
// Order of the two 16-bit words of a 32-bit value: the high word at the lower address
// ("high_first", Modbus convention) or the low word there ("low_first").
enum class WordOrder { kHighFirst, kLowFirst };

// Defaults are the map of docs/slide-drive.md, which the simulated drive serves unless
// told otherwise.
struct ModbusRegisterMap {
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

// Parses and validates board.json's drive.registers object: keys as the struct's, bits
// in [0, 15] and distinct within a word, the written registers (control, speed, target)
// not overlapping one another or anything read, and the scales such that
// max_speed_mm_s and the travel limits fit the registers. Errors are ConfigErrors naming
// the key ("board.json: drive.registers.speed.address: ...").
ModbusRegisterMap ParseModbusRegisterMap(const JsonReader& registers, double max_speed_mm_s,
                                         double travel_min_mm, double travel_max_mm);

}  // namespace mirrorscan

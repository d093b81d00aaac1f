#include "common/modbus/register_map.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace mirrorscan {
namespace {

constexpr int kMaxAddress = 65535;

ModbusTable ReadTable(const JsonReader& r, const std::vector<std::string>& choices,
                      const std::string& fallback) {
  const std::string table = r.Choice("table", choices, fallback);
  if (table == "coils") return ModbusTable::kCoils;
  if (table == "input") return ModbusTable::kInput;
  return ModbusTable::kHolding;
}

// Bits of one 16-bit word must be distinct.
void CheckDistinctBits(const JsonReader& r, const std::vector<std::pair<const char*, int>>& bits) {
  std::map<int, const char*> seen;
  for (const auto& [key, bit] : bits) {
    const auto [it, inserted] = seen.emplace(bit, key);
    if (!inserted) r.Fail(key, "bit " + std::to_string(bit) + " is also " + it->second);
  }
}

}  // namespace

ModbusRegisterMap ParseModbusRegisterMap(const JsonReader& regs, double max_speed_mm_s,
                                         double travel_min_mm, double travel_max_mm) {
  const ModbusRegisterMap defaults;
  ModbusRegisterMap c;
  regs.AllowOnly({"control", "status", "fault_code", "speed", "position", "target"});

  const JsonReader control = regs.Object("control");
  control.AllowOnly(
      {"table", "address", "enable_bit", "home_bit", "start_bit", "stop_bit", "fault_reset_bit"});
  auto& ctl = c.control;
  ctl.table = ReadTable(control, {"holding", "coils"}, "holding");
  ctl.address = control.Integer("address", std::nullopt, 0, kMaxAddress);
  ctl.enable_bit = control.Integer("enable_bit", defaults.control.enable_bit, 0, 15);
  ctl.home_bit = control.Integer("home_bit", defaults.control.home_bit, 0, 15);
  ctl.start_bit = control.Integer("start_bit", defaults.control.start_bit, 0, 15);
  ctl.stop_bit = control.Integer("stop_bit", defaults.control.stop_bit, 0, 15);
  ctl.fault_reset_bit = control.Integer("fault_reset_bit", defaults.control.fault_reset_bit, 0, 15);
  CheckDistinctBits(control, {{"enable_bit", ctl.enable_bit},
                              {"home_bit", ctl.home_bit},
                              {"start_bit", ctl.start_bit},
                              {"stop_bit", ctl.stop_bit},
                              {"fault_reset_bit", ctl.fault_reset_bit}});
  if (ctl.table == ModbusTable::kCoils) {
    for (int bit :
         {ctl.enable_bit, ctl.home_bit, ctl.start_bit, ctl.stop_bit, ctl.fault_reset_bit}) {
      if (ctl.address + bit > kMaxAddress) control.Fail("address", "coil address + bit > 65535");
    }
  }

  const JsonReader status = regs.Object("status");
  status.AllowOnly({"table", "address", "enabled_bit", "homed_bit", "moving_bit", "fault_bit"});
  auto& st = c.status;
  st.table = ReadTable(status, {"holding", "input"}, "input");
  st.address = status.Integer("address", std::nullopt, 0, kMaxAddress);
  st.enabled_bit = status.Integer("enabled_bit", defaults.status.enabled_bit, 0, 15);
  st.homed_bit = status.Integer("homed_bit", defaults.status.homed_bit, 0, 15);
  st.moving_bit = status.Integer("moving_bit", defaults.status.moving_bit, 0, 15);
  st.fault_bit = status.Integer("fault_bit", defaults.status.fault_bit, 0, 15);
  CheckDistinctBits(status, {{"enabled_bit", st.enabled_bit},
                             {"homed_bit", st.homed_bit},
                             {"moving_bit", st.moving_bit},
                             {"fault_bit", st.fault_bit}});

  const JsonReader fault = regs.Object("fault_code");
  fault.AllowOnly({"table", "address"});
  c.fault_code.table = ReadTable(fault, {"holding", "input"}, "input");
  c.fault_code.address = fault.Integer("address", std::nullopt, 0, kMaxAddress);

  const JsonReader speed = regs.Object("speed");
  speed.AllowOnly({"address", "counts_per_mm_s"});
  c.speed.address = speed.Integer("address", std::nullopt, 0, kMaxAddress);
  c.speed.counts_per_mm_s = speed.Number("counts_per_mm_s", std::nullopt, 1e-6, 1e6);
  if (max_speed_mm_s * c.speed.counts_per_mm_s > 65535.0) {
    speed.Fail("counts_per_mm_s", "max_speed_mm_s * counts_per_mm_s exceeds the 16-bit register");
  }

  const JsonReader position = regs.Object("position");
  position.AllowOnly({"table", "address", "counts_per_mm", "word_order"});
  auto& pos = c.position;
  pos.table = ReadTable(position, {"holding", "input"}, "input");
  pos.address = position.Integer("address", std::nullopt, 0, kMaxAddress - 1);
  pos.counts_per_mm = position.Number("counts_per_mm", std::nullopt, 1e-6, 1e9);
  pos.word_order =
      position.Choice("word_order", {"high_first", "low_first"}, "high_first") == "high_first"
          ? WordOrder::kHighFirst
          : WordOrder::kLowFirst;
  const double max_abs_mm = std::max(std::abs(travel_min_mm), std::abs(travel_max_mm));
  if (max_abs_mm * pos.counts_per_mm > static_cast<double>(INT32_MAX)) {
    position.Fail("counts_per_mm", "travel_mm * counts_per_mm exceeds a signed 32-bit value");
  }

  const JsonReader target = regs.Object("target");
  target.AllowOnly({"address"});
  c.target.address = target.Integer("address", std::nullopt, 0, kMaxAddress - 1);

  // The holding registers (or coils) written must not overlap one another, and nothing
  // read may overlap them: a typo in an address would otherwise command the wrong thing.
  struct Range {
    const JsonReader* reader;
    ModbusTable table;
    int first;
    int last;
  };
  const bool coils = ctl.table == ModbusTable::kCoils;
  const int ctl_first = coils ? ctl.address + std::min({ctl.enable_bit, ctl.home_bit, ctl.start_bit,
                                                        ctl.stop_bit, ctl.fault_reset_bit})
                              : ctl.address;
  const int ctl_last = coils ? ctl.address + std::max({ctl.enable_bit, ctl.home_bit, ctl.start_bit,
                                                       ctl.stop_bit, ctl.fault_reset_bit})
                             : ctl.address;
  const std::vector<Range> ranges = {
      {&control, ctl.table, ctl_first, ctl_last},
      {&speed, ModbusTable::kHolding, c.speed.address, c.speed.address},
      {&target, ModbusTable::kHolding, c.target.address, c.target.address + 1},
      {&status, st.table, st.address, st.address},
      {&fault, c.fault_code.table, c.fault_code.address, c.fault_code.address},
      {&position, pos.table, pos.address, pos.address + 1},
  };
  constexpr size_t kWritten = 3;  // the first three are written; the others only read
  for (size_t i = 0; i < ranges.size(); ++i) {
    for (size_t j = 0; j < std::min(i, kWritten); ++j) {
      const Range& a = ranges[i];
      const Range& b = ranges[j];
      if (a.table == b.table && a.first <= b.last && b.first <= a.last) {
        a.reader->Fail("address", "overlaps " + b.reader->KeyPath("address"));
      }
    }
  }
  return c;
}

}  // namespace mirrorscan

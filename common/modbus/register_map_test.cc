#include "common/modbus/register_map.h"

#include <string>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

// docs/slide-drive.md's example map, written out in full.
constexpr const char* kDocumentedMap = R"({
  "control": {"table": "holding", "address": 0, "enable_bit": 0, "home_bit": 1,
              "start_bit": 2, "stop_bit": 3, "fault_reset_bit": 4},
  "status": {"table": "input", "address": 0, "enabled_bit": 0, "homed_bit": 1,
             "moving_bit": 2, "fault_bit": 3},
  "fault_code": {"table": "input", "address": 1},
  "speed": {"address": 1, "counts_per_mm_s": 10},
  "target": {"address": 2},
  "position": {"table": "input", "address": 2, "counts_per_mm": 100,
               "word_order": "high_first"}
})";

ModbusRegisterMap Parse(const std::string& text) {
  const nlohmann::json json = JsonReader::ParseText(text, "board.json");
  return ParseModbusRegisterMap(JsonReader(json, "board.json", "drive.registers"), 500.0, 0.0,
                                1900.0);
}

std::string ErrorOf(const std::string& text) {
  try {
    Parse(text);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

void ExpectSameMap(const ModbusRegisterMap& a, const ModbusRegisterMap& b) {
  EXPECT_EQ(a.control.table, b.control.table);
  EXPECT_EQ(a.control.address, b.control.address);
  EXPECT_EQ(a.control.enable_bit, b.control.enable_bit);
  EXPECT_EQ(a.control.home_bit, b.control.home_bit);
  EXPECT_EQ(a.control.start_bit, b.control.start_bit);
  EXPECT_EQ(a.control.stop_bit, b.control.stop_bit);
  EXPECT_EQ(a.control.fault_reset_bit, b.control.fault_reset_bit);
  EXPECT_EQ(a.status.table, b.status.table);
  EXPECT_EQ(a.status.address, b.status.address);
  EXPECT_EQ(a.status.enabled_bit, b.status.enabled_bit);
  EXPECT_EQ(a.status.homed_bit, b.status.homed_bit);
  EXPECT_EQ(a.status.moving_bit, b.status.moving_bit);
  EXPECT_EQ(a.status.fault_bit, b.status.fault_bit);
  EXPECT_EQ(a.fault_code.table, b.fault_code.table);
  EXPECT_EQ(a.fault_code.address, b.fault_code.address);
  EXPECT_EQ(a.speed.address, b.speed.address);
  EXPECT_EQ(a.speed.counts_per_mm_s, b.speed.counts_per_mm_s);
  EXPECT_EQ(a.target.address, b.target.address);
  EXPECT_EQ(a.position.table, b.position.table);
  EXPECT_EQ(a.position.address, b.position.address);
  EXPECT_EQ(a.position.counts_per_mm, b.position.counts_per_mm);
  EXPECT_EQ(a.position.word_order, b.position.word_order);
}

// The defaults (what the simulated drive serves unless told otherwise) are the map the
// documentation gives.
TEST(ModbusRegisterMapTest, DefaultsAreTheDocumentedMap) {
  ExpectSameMap(ModbusRegisterMap{}, Parse(kDocumentedMap));
}

TEST(ModbusRegisterMapTest, BitsLeftOutTakeTheDefaults) {
  const ModbusRegisterMap map = Parse(R"({
    "control": {"table": "coils", "address": 16},
    "status": {"table": "holding", "address": 10},
    "fault_code": {"table": "holding", "address": 12},
    "speed": {"address": 1, "counts_per_mm_s": 20},
    "target": {"address": 2},
    "position": {"address": 20, "counts_per_mm": 50, "word_order": "low_first"}})");
  ModbusRegisterMap expected;
  expected.control.table = ModbusTable::kCoils;
  expected.control.address = 16;
  expected.status.table = ModbusTable::kHolding;
  expected.status.address = 10;
  expected.fault_code.table = ModbusTable::kHolding;
  expected.fault_code.address = 12;
  expected.speed.counts_per_mm_s = 20.0;
  expected.position.address = 20;
  expected.position.counts_per_mm = 50.0;
  expected.position.word_order = WordOrder::kLowFirst;
  ExpectSameMap(map, expected);
}

TEST(ModbusRegisterMapTest, ErrorsNameTheKey) {
  nlohmann::json base = JsonReader::ParseText(kDocumentedMap, "board.json");
  auto error_after = [&](const std::string& pointer, const nlohmann::json& value) {
    nlohmann::json edited = base;
    edited[nlohmann::json::json_pointer(pointer)] = value;
    return ErrorOf(edited.dump());
  };
  EXPECT_EQ(error_after("/control/start_bit", 1),
            "board.json: drive.registers.control.start_bit: bit 1 is also home_bit");
  EXPECT_EQ(error_after("/target/address", 0),
            "board.json: drive.registers.target.address: overlaps "
            "drive.registers.control.address");
  EXPECT_EQ(error_after("/speed/counts_per_mm_s", 200),
            "board.json: drive.registers.speed.counts_per_mm_s: max_speed_mm_s * "
            "counts_per_mm_s exceeds the 16-bit register");
  EXPECT_NE(error_after("/position/counts_per_mm", 2e6)
                .find("drive.registers.position."
                      "counts_per_mm: travel_mm"),
            std::string::npos);
}

}  // namespace
}  // namespace mirrorscan

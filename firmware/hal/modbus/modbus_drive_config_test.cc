#include "firmware/hal/modbus/modbus_drive_config.h"

#include <functional>
#include <string>

#include <gtest/gtest.h>

namespace mirrorscan::hal {
namespace {

const std::string kFixture =
    std::string(MIRRORSCAN_SOURCE_DIR) + "/firmware/hal/modbus/testdata/board_drive.json";

nlohmann::json Fixture() { return JsonReader::ParseFile(kFixture); }

// Parses `board` (a board.json with a "drive" object); returns the error, "" if none.
std::string ErrorOf(const nlohmann::json& board) {
  try {
    ParseModbusDriveConfig(JsonReader(board, "board.json").Object("drive"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string ErrorAfter(const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json board = Fixture();
  edit(board["drive"]);
  return ErrorOf(board);
}

TEST(ModbusDriveConfigTest, ReadsTheDocumentedExample) {
  const ModbusDriveConfig c = LoadModbusDriveConfig(kFixture);
  EXPECT_EQ(c.transport, ModbusDriveConfig::Transport::kTcp);
  EXPECT_EQ(c.host, "127.0.0.1");
  EXPECT_EQ(c.port, 1502);
  EXPECT_EQ(c.slave_id, 1);
  EXPECT_DOUBLE_EQ(c.response_timeout_s, 0.1);
  EXPECT_EQ(c.retries, 2);
  EXPECT_DOUBLE_EQ(c.max_speed_mm_s, 500.0);
  EXPECT_DOUBLE_EQ(c.travel_min_mm, 0.0);
  EXPECT_DOUBLE_EQ(c.travel_max_mm, 1900.0);
  EXPECT_EQ(c.registers.control.table, ModbusTable::kHolding);
  EXPECT_EQ(c.registers.control.fault_reset_bit, 4);
  EXPECT_EQ(c.registers.status.table, ModbusTable::kInput);
  EXPECT_EQ(c.registers.status.fault_bit, 3);
  EXPECT_EQ(c.registers.fault_code.address, 1);
  EXPECT_DOUBLE_EQ(c.registers.speed.counts_per_mm_s, 10.0);
  EXPECT_EQ(c.registers.target.address, 2);
  EXPECT_EQ(c.registers.position.address, 2);
  EXPECT_DOUBLE_EQ(c.registers.position.counts_per_mm, 100.0);
  EXPECT_EQ(c.registers.position.word_order, WordOrder::kHighFirst);
}

TEST(ModbusDriveConfigTest, ReadsAnRtuLink) {
  nlohmann::json board = Fixture();
  board["drive"]["link"] = {{"transport", "rtu"},
                            {"device", "/dev/ttyAMA1"},
                            {"baud", 19200},
                            {"parity", "even"},
                            {"stop_bits", 1}};
  board["drive"]["registers"]["control"]["table"] = "coils";
  board["drive"]["registers"]["position"]["word_order"] = "low_first";
  const ModbusDriveConfig c = ParseModbusDriveConfig(JsonReader(board, "b.json").Object("drive"));
  EXPECT_EQ(c.transport, ModbusDriveConfig::Transport::kRtu);
  EXPECT_EQ(c.device, "/dev/ttyAMA1");
  EXPECT_EQ(c.baud, 19200);
  EXPECT_EQ(c.parity, 'E');
  EXPECT_EQ(c.data_bits, 8);
  EXPECT_EQ(c.registers.control.table, ModbusTable::kCoils);
  EXPECT_EQ(c.registers.position.word_order, WordOrder::kLowFirst);
}

TEST(ModbusDriveConfigTest, ErrorsNameTheKey) {
  EXPECT_EQ(ErrorOf(nlohmann::json::object()), "board.json: drive: missing");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["link"]["transport"] = "udp"; }),
            "board.json: drive.link.transport: \"udp\" is not one of: tcp, rtu");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["link"]["port"] = 70000; }),
            "board.json: drive.link.port: must be in [1, 65535], got 70000");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["link"]["device"] = "/dev/ttyS0"; }),
            "board.json: drive.link.device: unknown key (expected one of: transport, host, "
            "port)");
  EXPECT_EQ(ErrorAfter([](auto& d) {
              d["link"] = {{"transport", "rtu"}, {"device", "/dev/ttyS0"}, {"parity", "mark"}};
            }),
            "board.json: drive.link.parity: \"mark\" is not one of: none, even, odd");
  EXPECT_EQ(ErrorAfter([](auto& d) {
              d["link"] = {{"transport", "rtu"}, {"device", "/dev/ttyS0"}};
              d["slave_id"] = 0;
            }),
            "board.json: drive.slave_id: must be in [1, 247], got 0");
  EXPECT_EQ(
      ErrorAfter([](auto& d) { d["retry"] = 3; }).rfind("board.json: drive.retry: unknown key", 0),
      0u);
  EXPECT_EQ(ErrorAfter([](auto& d) {
              d["response_timeout_s"] = 0;
            }).rfind("board.json: drive.response_timeout_s: must be in", 0),
            0u);
  EXPECT_EQ(ErrorAfter([](auto& d) {
              d["travel_mm"] = {1900, 0};
            }),
            "board.json: drive.travel_mm: expected [min, max] with min < max");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["speed"].erase("address"); }),
            "board.json: drive.registers.speed.address: missing (expected an integer)");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["control"]["start_bit"] = 1; }),
            "board.json: drive.registers.control.start_bit: bit 1 is also home_bit");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["status"]["fault_bit"] = 16; }),
            "board.json: drive.registers.status.fault_bit: must be in [0, 15], got 16");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["control"]["table"] = "input"; }),
            "board.json: drive.registers.control.table: \"input\" is not one of: holding, coils");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["position"]["word_order"] = "big"; }),
            "board.json: drive.registers.position.word_order: \"big\" is not one of: "
            "high_first, low_first");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["target"]["address"] = 0; }),
            "board.json: drive.registers.target.address: overlaps "
            "drive.registers.control.address");
  EXPECT_EQ(ErrorAfter([](auto& d) {
              d["registers"]["status"]["table"] = "holding";
              d["registers"]["status"]["address"] = 3;
            }),
            "board.json: drive.registers.status.address: overlaps drive.registers.target.address");
  EXPECT_EQ(ErrorAfter([](auto& d) { d["registers"]["speed"]["counts_per_mm_s"] = 1000; }),
            "board.json: drive.registers.speed.counts_per_mm_s: max_speed_mm_s * "
            "counts_per_mm_s exceeds the 16-bit register");
}

}  // namespace
}  // namespace mirrorscan::hal

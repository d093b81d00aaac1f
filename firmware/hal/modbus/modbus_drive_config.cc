#include "firmware/hal/modbus/modbus_drive_config.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace mirrorscan::hal {
namespace {

void ParseLink(const JsonReader& link, ModbusDriveConfig& c) {
  const std::string transport = link.Choice("transport", {"tcp", "rtu"});
  if (transport == "tcp") {
    link.AllowOnly({"transport", "host", "port"});
    c.transport = ModbusDriveConfig::Transport::kTcp;
    c.host = link.String("host");
    if (c.host.empty()) link.Fail("host", "must not be empty");
    c.port = link.Integer("port", 502, 1, 65535);
  } else {
    link.AllowOnly({"transport", "device", "baud", "parity", "data_bits", "stop_bits"});
    c.transport = ModbusDriveConfig::Transport::kRtu;
    c.device = link.String("device");
    if (c.device.empty()) link.Fail("device", "must not be empty");
    c.baud = link.Integer("baud", 115200, 300, 4000000);
    const std::string parity = link.Choice("parity", {"none", "even", "odd"}, "none");
    c.parity = parity == "none" ? 'N' : parity == "even" ? 'E' : 'O';
    c.data_bits = link.Integer("data_bits", 8, 5, 8);
    c.stop_bits = link.Integer("stop_bits", 1, 1, 2);
  }
}

}  // namespace

ModbusDriveConfig ParseModbusDriveConfig(const JsonReader& drive) {
  drive.AllowOnly({"backend", "link", "slave_id", "response_timeout_s", "retries", "max_speed_mm_s",
                   "travel_mm", "registers"});
  drive.Choice("backend", {"modbus"}, "modbus");
  ModbusDriveConfig c;
  ParseLink(drive.Object("link"), c);
  c.slave_id = c.transport == ModbusDriveConfig::Transport::kRtu
                   ? drive.Integer("slave_id", 1, 1, 247)
                   : drive.Integer("slave_id", 1, 0, 255);
  c.response_timeout_s = drive.Number("response_timeout_s", 0.1, 0.001, 10.0);
  c.retries = drive.Integer("retries", 2, 0, 10);
  c.max_speed_mm_s = drive.Number("max_speed_mm_s", std::nullopt, 1e-3, 1e5);
  const std::vector<double> travel = drive.Numbers("travel_mm", 2);
  if (!(travel[0] < travel[1])) drive.Fail("travel_mm", "expected [min, max] with min < max");
  c.travel_min_mm = travel[0];
  c.travel_max_mm = travel[1];
  c.registers = ParseModbusRegisterMap(drive.Object("registers"), c.max_speed_mm_s, c.travel_min_mm,
                                       c.travel_max_mm);
  return c;
}

ModbusDriveConfig LoadModbusDriveConfig(const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  const JsonReader board(json, board_json.string());
  return ParseModbusDriveConfig(board.Object("drive"));
}

}  // namespace mirrorscan::hal

#include "firmware/hal/modbus/modbus_slide_drive.h"

#include <cerrno>
#include <cmath>
#include <sstream>

#include <modbus.h>

namespace mirrorscan::hal {
namespace {

using Kind = HardwareError::Kind;

std::string Seconds(double s) {
  std::ostringstream out;
  out << s << " s";
  return out.str();
}

// Modbus exception responses: the drive answered and refused. Retrying will not help.
bool IsModbusException(int err) { return err > MODBUS_ENOBASE && err <= EMBXGTAR; }

std::string TableName(ModbusTable table) {
  switch (table) {
    case ModbusTable::kCoils:
      return "coil";
    case ModbusTable::kHolding:
      return "holding";
    case ModbusTable::kInput:
      return "input";
  }
  return "?";
}

}  // namespace

ModbusSlideDrive::ModbusSlideDrive(const ModbusDriveConfig& config) : config_(config) {
  if (config_.transport == ModbusDriveConfig::Transport::kTcp) {
    const std::string port = std::to_string(config_.port);
    ctx_ = modbus_new_tcp_pi(config_.host.c_str(), port.c_str());
  } else {
    ctx_ = modbus_new_rtu(config_.device.c_str(), config_.baud, config_.parity, config_.data_bits,
                          config_.stop_bits);
  }
  if (ctx_ == nullptr) {
    throw HardwareError(Kind::kIo,
                        Describe() + ": cannot create the context: " + modbus_strerror(errno));
  }
  const double timeout = config_.response_timeout_s;
  const auto sec = static_cast<uint32_t>(timeout);
  const auto usec = static_cast<uint32_t>(std::lround((timeout - sec) * 1e6));
  if (modbus_set_slave(ctx_, config_.slave_id) == -1 ||
      modbus_set_response_timeout(ctx_, sec, usec) == -1 ||
      modbus_set_byte_timeout(ctx_, sec, usec) == -1 ||
      modbus_set_error_recovery(ctx_, MODBUS_ERROR_RECOVERY_NONE) == -1) {
    const std::string error = modbus_strerror(errno);
    modbus_free(ctx_);
    throw HardwareError(Kind::kIo, Describe() + ": cannot configure the context: " + error);
  }
  try {
    std::lock_guard lock(mutex_);
    Transact("open the link", [](modbus_t*) { return 0; });
  } catch (...) {
    modbus_free(ctx_);
    throw;
  }
}

ModbusSlideDrive::~ModbusSlideDrive() {
  std::lock_guard lock(mutex_);
  Disconnect();
  modbus_free(ctx_);
}

std::string ModbusSlideDrive::Describe() const {
  std::ostringstream out;
  if (config_.transport == ModbusDriveConfig::Transport::kTcp) {
    out << "modbus tcp " << config_.host << ":" << config_.port;
  } else {
    out << "modbus rtu " << config_.device;
  }
  out << " slave " << config_.slave_id;
  return out.str();
}

void ModbusSlideDrive::Disconnect() {
  if (connected_) modbus_close(ctx_);
  connected_ = false;
}

void ModbusSlideDrive::Transact(const std::string& what,
                                const std::function<int(modbus_t*)>& request) {
  const int attempts = 1 + config_.retries;
  std::string last_error;
  bool timed_out = false;
  for (int attempt = 0; attempt < attempts; ++attempt) {
    if (!connected_) {
      if (modbus_connect(ctx_) == -1) {
        const int err = errno;
        last_error = std::string("cannot connect: ") + modbus_strerror(err);
        timed_out = err == ETIMEDOUT || err == EINPROGRESS;
        continue;
      }
      connected_ = true;
    }
    if (request(ctx_) != -1) return;
    const int err = errno;
    if (IsModbusException(err)) {
      throw HardwareError(Kind::kRejected,
                          Describe() + ": " + what + ": drive refused: " + modbus_strerror(err));
    }
    last_error = modbus_strerror(err);
    timed_out = err == ETIMEDOUT;
    if (config_.transport == ModbusDriveConfig::Transport::kRtu &&
        (err == ETIMEDOUT || err > MODBUS_ENOBASE)) {
      modbus_flush(ctx_);  // the serial line is fine; drop a late or garbled answer
    } else {
      Disconnect();  // TCP: a fresh connection can never deliver a late answer
    }
  }
  throw HardwareError(timed_out ? Kind::kTimeout : Kind::kIo,
                      Describe() + ": " + what + ": " + last_error + " (" +
                          std::to_string(attempts) + " attempts, response timeout " +
                          Seconds(config_.response_timeout_s) + ")");
}

void ModbusSlideDrive::WriteControl(const std::string& what, int command_bit) {
  const auto& ctl = config_.registers.control;
  if (ctl.table == ModbusTable::kCoils) {
    const int bit = command_bit >= 0 ? command_bit : ctl.enable_bit;
    const int value = command_bit >= 0 ? 1 : (enabled_ ? 1 : 0);
    Transact(what + " (coil " + std::to_string(ctl.address + bit) + ")",
             [&](modbus_t* ctx) { return modbus_write_bit(ctx, ctl.address + bit, value); });
    return;
  }
  uint16_t word = enabled_ ? static_cast<uint16_t>(1u << ctl.enable_bit) : 0;
  if (command_bit >= 0) word |= static_cast<uint16_t>(1u << command_bit);
  Transact(what + " (holding " + std::to_string(ctl.address) + ")",
           [&](modbus_t* ctx) { return modbus_write_register(ctx, ctl.address, word); });
}

uint16_t ModbusSlideDrive::ReadRegister(const std::string& what, ModbusTable table, int address) {
  uint16_t value = 0;
  Transact("read " + what + " (" + TableName(table) + " " + std::to_string(address) + ")",
           [&](modbus_t* ctx) {
             return table == ModbusTable::kInput
                        ? modbus_read_input_registers(ctx, address, 1, &value)
                        : modbus_read_registers(ctx, address, 1, &value);
           });
  return value;
}

void ModbusSlideDrive::WriteInt32(const std::string& what, int address, int32_t value) {
  const auto bits = static_cast<uint32_t>(value);
  const auto high = static_cast<uint16_t>(bits >> 16);
  const auto low = static_cast<uint16_t>(bits & 0xffffu);
  const bool high_first = config_.registers.position.word_order == WordOrder::kHighFirst;
  const uint16_t words[2] = {high_first ? high : low, high_first ? low : high};
  Transact("write " + what + " (holding " + std::to_string(address) + ")",
           [&](modbus_t* ctx) { return modbus_write_registers(ctx, address, 2, words); });
}

int32_t ModbusSlideDrive::ReadInt32(const std::string& what, ModbusTable table, int address) {
  uint16_t words[2] = {0, 0};
  Transact("read " + what + " (" + TableName(table) + " " + std::to_string(address) + ")",
           [&](modbus_t* ctx) {
             return table == ModbusTable::kInput
                        ? modbus_read_input_registers(ctx, address, 2, words)
                        : modbus_read_registers(ctx, address, 2, words);
           });
  const bool high_first = config_.registers.position.word_order == WordOrder::kHighFirst;
  const uint32_t high = high_first ? words[0] : words[1];
  const uint32_t low = high_first ? words[1] : words[0];
  return static_cast<int32_t>((high << 16) | low);
}

void ModbusSlideDrive::Enable(bool on) {
  std::lock_guard lock(mutex_);
  const bool before = enabled_;
  enabled_ = on;
  try {
    WriteControl(on ? "enable" : "disable", -1);
  } catch (...) {
    // Disabling: keep the level off so later commands never re-enable by accident.
    if (on) enabled_ = before;
    throw;
  }
}

void ModbusSlideDrive::StartHome() {
  std::lock_guard lock(mutex_);
  WriteControl("home", config_.registers.control.home_bit);
}

void ModbusSlideDrive::SetSpeed(double mm_per_s) {
  if (!(mm_per_s > 0.0) || mm_per_s > config_.max_speed_mm_s) {
    throw HardwareError(Kind::kInvalidArgument, Describe() + ": speed " + std::to_string(mm_per_s) +
                                                    " mm/s outside (0, " +
                                                    std::to_string(config_.max_speed_mm_s) + "]");
  }
  const long counts = std::lround(mm_per_s * config_.registers.speed.counts_per_mm_s);
  if (counts < 1 || counts > 65535) {
    throw HardwareError(Kind::kInvalidArgument, Describe() + ": speed " + std::to_string(mm_per_s) +
                                                    " mm/s is not representable in the register");
  }
  std::lock_guard lock(mutex_);
  const auto value = static_cast<uint16_t>(counts);
  Transact("write speed (holding " + std::to_string(config_.registers.speed.address) + ")",
           [&](modbus_t* ctx) {
             return modbus_write_register(ctx, config_.registers.speed.address, value);
           });
}

void ModbusSlideDrive::Start(double target_mm) {
  if (!(target_mm >= config_.travel_min_mm && target_mm <= config_.travel_max_mm)) {
    throw HardwareError(Kind::kInvalidArgument,
                        Describe() + ": target " + std::to_string(target_mm) +
                            " mm outside the travel [" + std::to_string(config_.travel_min_mm) +
                            ", " + std::to_string(config_.travel_max_mm) + "] mm");
  }
  std::lock_guard lock(mutex_);
  const auto counts =
      static_cast<int32_t>(std::lround(target_mm * config_.registers.position.counts_per_mm));
  WriteInt32("target", config_.registers.target.address, counts);
  WriteControl("start", config_.registers.control.start_bit);
}

void ModbusSlideDrive::DoStop() {
  std::lock_guard lock(mutex_);
  WriteControl("stop", config_.registers.control.stop_bit);
}

void ModbusSlideDrive::ResetFault() {
  std::lock_guard lock(mutex_);
  WriteControl("fault reset", config_.registers.control.fault_reset_bit);
}

double ModbusSlideDrive::Position() {
  std::lock_guard lock(mutex_);
  const int32_t counts =
      ReadInt32("position", config_.registers.position.table, config_.registers.position.address);
  return counts / config_.registers.position.counts_per_mm;
}

SlideStatus ModbusSlideDrive::Status() {
  std::lock_guard lock(mutex_);
  const auto& st = config_.registers.status;
  const auto& fc = config_.registers.fault_code;
  uint16_t word = 0;
  uint16_t code = 0;
  if (fc.table == st.table && fc.address == st.address + 1) {
    // One read gives a consistent snapshot of status and fault code.
    uint16_t words[2] = {0, 0};
    Transact("read status and fault code (" + TableName(st.table) + " " +
                 std::to_string(st.address) + ")",
             [&](modbus_t* ctx) {
               return st.table == ModbusTable::kInput
                          ? modbus_read_input_registers(ctx, st.address, 2, words)
                          : modbus_read_registers(ctx, st.address, 2, words);
             });
    word = words[0];
    code = words[1];
  } else {
    word = ReadRegister("status", st.table, st.address);
    if (word & (1u << st.fault_bit)) code = ReadRegister("fault code", fc.table, fc.address);
  }
  SlideStatus status;
  status.enabled = word & (1u << st.enabled_bit);
  status.homed = word & (1u << st.homed_bit);
  status.moving = word & (1u << st.moving_bit);
  status.fault = word & (1u << st.fault_bit);
  status.fault_code = status.fault ? code : 0;
  return status;
}

}  // namespace mirrorscan::hal

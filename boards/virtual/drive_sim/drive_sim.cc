#include "boards/virtual/drive_sim/drive_sim.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <modbus.h>

#include "common/realtime/realtime.h"

namespace mirrorscan::virtual_cabinet {
namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

[[noreturn]] void ThrowErrno(const std::string& what) {
  throw std::runtime_error("drive sim: " + what + ": " + std::strerror(errno));
}

// Registers needed to cover `address` (+ `count` - 1) in a table.
void Need(int& size, int address, int count) { size = std::max(size, address + count); }

}  // namespace

DriveSim::DriveSim(const DriveSimConfig& config) : config_(config), model_(config.model, NowNs()) {
  const auto& m = config_.map;
  int bits = 0;
  int holding = 0;
  int input = 0;
  auto need = [&](ModbusTable table, int address, int count) {
    Need(table == ModbusTable::kCoils     ? bits
         : table == ModbusTable::kHolding ? holding
                                          : input,
         address, count);
  };
  need(m.control.table, m.control.address, m.control.table == ModbusTable::kCoils ? 16 : 1);
  need(m.status.table, m.status.address, 1);
  need(m.fault_code.table, m.fault_code.address, 1);
  need(ModbusTable::kHolding, m.speed.address, 1);
  need(ModbusTable::kHolding, m.target.address, 2);
  need(m.position.table, m.position.address, 2);
  mapping_ = modbus_mapping_new(bits, 0, holding, input);
  if (mapping_ == nullptr) ThrowErrno("modbus_mapping_new");
  if (pipe2(wake_fds_, O_CLOEXEC | O_NONBLOCK) != 0) ThrowErrno("pipe2");
}

std::unique_ptr<DriveSim> DriveSim::ServeTcp(const DriveSimConfig& config) {
  std::unique_ptr<DriveSim> sim(new DriveSim(config));
  sim->tcp_ = true;
  sim->listen_fd_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (sim->listen_fd_ < 0) ThrowErrno("socket");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;  // ephemeral
  socklen_t length = sizeof(addr);
  if (bind(sim->listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      listen(sim->listen_fd_, 4) != 0 ||
      getsockname(sim->listen_fd_, reinterpret_cast<sockaddr*>(&addr), &length) != 0) {
    ThrowErrno("listen on 127.0.0.1");
  }
  sim->port_ = ntohs(addr.sin_port);
  sim->ctx_ = modbus_new_tcp("127.0.0.1", sim->port_);
  if (sim->ctx_ == nullptr) ThrowErrno("modbus_new_tcp");
  modbus_set_slave(sim->ctx_, config.slave_id);
  modbus_set_indication_timeout(sim->ctx_, 1, 0);  // a partial request never blocks for long
  sim->thread_ = std::thread([s = sim.get()] { s->Run(); });
  sim->realtime_error_ = RunThreadFirst(sim->thread_, 20);
  return sim;
}

std::unique_ptr<DriveSim> DriveSim::ServeRtu(const DriveSimConfig& config) {
  std::unique_ptr<DriveSim> sim(new DriveSim(config));
  sim->tcp_ = false;
  char name[256] = {};
  if (openpty(&sim->client_fd_, &sim->pty_slave_fd_, name, nullptr, nullptr) != 0) {
    ThrowErrno("openpty");
  }
  fcntl(sim->client_fd_, F_SETFD, FD_CLOEXEC);
  fcntl(sim->pty_slave_fd_, F_SETFD, FD_CLOEXEC);
  // Raw until the client opens it (libmodbus then sets its own raw mode).
  termios tios{};
  if (tcgetattr(sim->pty_slave_fd_, &tios) == 0) {
    cfmakeraw(&tios);
    tcsetattr(sim->pty_slave_fd_, TCSANOW, &tios);
  }
  sim->device_ = name;
  // The server side talks on the pty master: libmodbus's RTU framing on a descriptor we
  // own (never modbus_connect/modbus_close, which would treat it as a serial port).
  sim->ctx_ = modbus_new_rtu(name, 115200, 'N', 8, 1);
  if (sim->ctx_ == nullptr) ThrowErrno("modbus_new_rtu");
  modbus_set_socket(sim->ctx_, sim->client_fd_);
  if (getenv("DRIVE_SIM_DEBUG")) modbus_set_debug(sim->ctx_, TRUE);
  modbus_set_slave(sim->ctx_, config.slave_id);
  modbus_set_indication_timeout(sim->ctx_, 1, 0);
  sim->thread_ = std::thread([s = sim.get()] { s->Run(); });
  sim->realtime_error_ = RunThreadFirst(sim->thread_, 20);
  return sim;
}

DriveSim::~DriveSim() {
  stop_ = true;
  Wake();
  if (thread_.joinable()) thread_.join();
  if (ctx_ != nullptr) {
    modbus_set_socket(ctx_, -1);
    modbus_free(ctx_);
  }
  for (int fd : {listen_fd_, client_fd_, pty_slave_fd_, wake_fds_[0], wake_fds_[1]}) {
    if (fd >= 0) close(fd);
  }
  if (mapping_ != nullptr) modbus_mapping_free(mapping_);
}

void DriveSim::Wake() {
  const char byte = 1;
  [[maybe_unused]] const ssize_t n = write(wake_fds_[1], &byte, 1);
}

DriveSimState DriveSim::State() {
  std::lock_guard lock(mutex_);
  model_.Advance(NowNs());
  return {model_.state(), requests_};
}

void DriveSim::InjectFault(int code) {
  std::lock_guard lock(mutex_);
  model_.InjectFault(code, NowNs());
}

void DriveSim::SetResponding(bool responding) { responding_ = responding; }

void DriveSim::DropConnection() {
  drop_ = true;
  Wake();
  // Return once the server thread has closed it (bounded: the thread only ever blocks
  // in poll, and for at most the indication timeout inside a request).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (drop_ && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void DriveSim::Run() {
  uint8_t request[MODBUS_MAX_ADU_LENGTH];
  while (!stop_) {
    pollfd fds[3] = {{wake_fds_[0], POLLIN, 0}, {client_fd_, POLLIN, 0}, {listen_fd_, POLLIN, 0}};
    const nfds_t count = tcp_ ? 3 : 2;
    if (poll(fds, count, -1) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    if (fds[0].revents != 0) {
      char buffer[64];
      while (read(wake_fds_[0], buffer, sizeof(buffer)) > 0) {
      }
      if (stop_) return;
      if (drop_) {
        if (tcp_ && client_fd_ >= 0) {
          close(client_fd_);
          client_fd_ = -1;
          modbus_set_socket(ctx_, -1);
        }
        drop_ = false;
        continue;
      }
    }
    if (tcp_ && (fds[2].revents & POLLIN)) {
      const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd >= 0) {
        if (client_fd_ >= 0) close(client_fd_);  // one client: the newest wins
        client_fd_ = fd;
        modbus_set_socket(ctx_, client_fd_);
      }
      continue;  // the old client's revents refer to a closed descriptor
    }
    if (client_fd_ < 0 || fds[1].revents == 0) continue;
    const int length = modbus_receive(ctx_, request);
    if (length > 0) {
      std::lock_guard lock(mutex_);
      ++requests_;
      if (responding_) Serve(request, length);
    } else if (length < 0) {
      if (tcp_) {  // closed by the client or garbage: wait for the next connection
        close(client_fd_);
        client_fd_ = -1;
        modbus_set_socket(ctx_, -1);
      } else {
        modbus_flush(ctx_);
      }
    }
  }
}

void DriveSim::Serve(uint8_t* request, int length) {
  model_.Advance(NowNs());
  PublishOutputs();
  modbus_reply(ctx_, request, length, mapping_);
  ApplyInputs(NowNs());
  PublishOutputs();
}

void DriveSim::PublishOutputs() {
  const auto& m = config_.map;
  const bool high_word_first = m.position.word_order == WordOrder::kHighFirst;
  const DriveModelState& s = model_.state();
  auto reg = [&](ModbusTable table, int address) -> uint16_t& {
    return table == ModbusTable::kInput ? mapping_->tab_input_registers[address]
                                        : mapping_->tab_registers[address];
  };
  uint16_t status = 0;
  if (s.enabled) status |= 1u << m.status.enabled_bit;
  if (s.homed) status |= 1u << m.status.homed_bit;
  if (s.moving) status |= 1u << m.status.moving_bit;
  if (s.fault) status |= 1u << m.status.fault_bit;
  reg(m.status.table, m.status.address) = status;
  reg(m.fault_code.table, m.fault_code.address) = static_cast<uint16_t>(s.fault_code);
  const auto counts = static_cast<uint32_t>(
      static_cast<int32_t>(std::lround(s.position_mm * m.position.counts_per_mm)));
  const auto high = static_cast<uint16_t>(counts >> 16);
  const auto low = static_cast<uint16_t>(counts & 0xffffu);
  reg(m.position.table, m.position.address) = high_word_first ? high : low;
  reg(m.position.table, m.position.address + 1) = high_word_first ? low : high;
}

void DriveSim::ApplyInputs(int64_t now_ns) {
  const auto& m = config_.map;
  const bool high_word_first = m.position.word_order == WordOrder::kHighFirst;
  // Control: the enable level and self-clearing command bits.
  const bool coils = m.control.table == ModbusTable::kCoils;
  auto bit = [&](int b) {
    return coils ? mapping_->tab_bits[m.control.address + b] != 0
                 : (mapping_->tab_registers[m.control.address] >> b) & 1u;
  };
  auto clear = [&](int b) {
    if (coils) {
      mapping_->tab_bits[m.control.address + b] = 0;
    } else {
      mapping_->tab_registers[m.control.address] &= static_cast<uint16_t>(~(1u << b));
    }
  };
  const uint16_t speed_counts = mapping_->tab_registers[m.speed.address];
  if (speed_counts != applied_speed_counts_) {
    applied_speed_counts_ = speed_counts;
    model_.SetSpeed(speed_counts / m.speed.counts_per_mm_s, now_ns);
  }
  if (bit(m.control.enable_bit) != model_.state().enabled)
    model_.SetEnabled(bit(m.control.enable_bit), now_ns);
  if (bit(m.control.fault_reset_bit)) model_.ResetFault(now_ns);
  if (bit(m.control.stop_bit)) {
    model_.Stop(now_ns);
  } else if (bit(m.control.home_bit)) {
    model_.Home(now_ns);
  } else if (bit(m.control.start_bit)) {
    const uint16_t* t = &mapping_->tab_registers[m.target.address];
    const uint32_t high = high_word_first ? t[0] : t[1];
    const uint32_t low = high_word_first ? t[1] : t[0];
    const auto target_counts = static_cast<int32_t>((high << 16) | low);
    model_.Start(target_counts / m.position.counts_per_mm, now_ns);
  }
  for (int b :
       {m.control.fault_reset_bit, m.control.stop_bit, m.control.home_bit, m.control.start_bit})
    clear(b);
}

}  // namespace mirrorscan::virtual_cabinet

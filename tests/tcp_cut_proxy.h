#pragma once

// A loopback TCP proxy for tests of dropped connections: it relays to an upstream port and
// cuts (or corrupts one byte of) the first N connections after a set number of bytes
// from the server. Test-only.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace mirrorscan::test_util {

class TcpCutProxy {
 public:
  enum class Mode { kCut, kCorrupt };

  // Connections 0..damaged_connections-1 are cut (or get one byte flipped) once
  // `after_bytes` bytes have come from upstream.
  TcpCutProxy(int upstream_port, uint64_t after_bytes, int damaged_connections,
              Mode mode = Mode::kCut)
      : upstream_port_(upstream_port),
        after_bytes_(after_bytes),
        damaged_connections_(damaged_connections),
        mode_(mode) {
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr = Loopback(0);
    if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
        ::listen(listen_fd_, 16) != 0) {
      throw std::runtime_error("proxy: cannot listen");
    }
    socklen_t length = sizeof(addr);
    ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &length);
    port_ = ntohs(addr.sin_port);
    acceptor_ = std::thread([this] { Accept(); });
  }

  ~TcpCutProxy() {
    stop_ = true;
    ::shutdown(listen_fd_, SHUT_RDWR);
    ::close(listen_fd_);
    acceptor_.join();
    std::lock_guard lock(mutex_);
    for (auto& t : relays_) t.join();
  }

  int port() const { return port_; }
  int connections() const { return connections_; }
  int damaged() const { return damaged_; }

 private:
  static sockaddr_in Loopback(int port) {
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return addr;
  }

  void Accept() {
    while (!stop_) {
      const int client = ::accept(listen_fd_, nullptr, nullptr);
      if (client < 0) return;
      const int index = connections_++;
      std::lock_guard lock(mutex_);
      relays_.emplace_back([this, client, index] { Relay(client, index < damaged_connections_); });
    }
  }

  void Relay(int client, bool damage) {
    const int upstream = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr = Loopback(upstream_port_);
    if (::connect(upstream, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
      ::close(upstream);
      ::close(client);
      return;
    }
    uint64_t downstream = 0;
    bool corrupted = false;
    std::vector<char> buffer(16384);
    pollfd fds[2] = {{client, POLLIN, 0}, {upstream, POLLIN, 0}};
    while (!stop_) {
      if (::poll(fds, 2, 100) < 0) break;
      if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) {
        const ssize_t n = ::recv(client, buffer.data(), buffer.size(), 0);
        if (n <= 0 || ::send(upstream, buffer.data(), static_cast<size_t>(n), MSG_NOSIGNAL) != n)
          break;
      }
      if (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) {
        ssize_t n = ::recv(upstream, buffer.data(), buffer.size(), 0);
        if (n <= 0) break;
        if (damage && downstream + static_cast<uint64_t>(n) > after_bytes_) {
          if (mode_ == Mode::kCut) {
            n = static_cast<ssize_t>(after_bytes_ - downstream);
            ::send(client, buffer.data(), static_cast<size_t>(n), MSG_NOSIGNAL);
            ++damaged_;
            break;
          }
          if (!corrupted) {
            buffer[after_bytes_ - downstream] ^= 0x5a;
            corrupted = true;
            ++damaged_;
          }
        }
        if (::send(client, buffer.data(), static_cast<size_t>(n), MSG_NOSIGNAL) != n) break;
        downstream += static_cast<uint64_t>(n);
      }
    }
    ::close(upstream);
    ::close(client);
  }

  const int upstream_port_;
  const uint64_t after_bytes_;
  const int damaged_connections_;
  const Mode mode_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> connections_{0};
  std::atomic<int> damaged_{0};
  std::thread acceptor_;
  std::mutex mutex_;
  std::vector<std::thread> relays_;
};

}  // namespace mirrorscan::test_util

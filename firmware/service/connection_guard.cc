#include "firmware/service/connection_guard.h"

#include <httplib.h>

#include "firmware/service/guarded_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>

namespace mirrorscan::service {
namespace {

using Clock = std::chrono::steady_clock;

void AddressOf(const sockaddr_storage& addr, std::string& ip, int& port) {
  char text[INET6_ADDRSTRLEN] = {};
  if (addr.ss_family == AF_INET) {
    const auto& in = reinterpret_cast<const sockaddr_in&>(addr);
    ::inet_ntop(AF_INET, &in.sin_addr, text, sizeof(text));
    port = ntohs(in.sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto& in6 = reinterpret_cast<const sockaddr_in6&>(addr);
    ::inet_ntop(AF_INET6, &in6.sin6_addr, text, sizeof(text));
    port = ntohs(in6.sin6_port);
  } else {
    port = 0;
  }
  ip = text;
}

// A socket stream whose reads give up at a deadline set per phase of the request (httplib's
// own SocketStream restarts its timeout at every read).
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(int fd, std::chrono::milliseconds write_timeout)
      : fd_(fd), write_timeout_(write_timeout) {}

  void set_read_deadline(Clock::time_point deadline) { read_deadline_ = deadline; }
  // Waits until a byte can be read (or the peer closed) before the deadline.
  bool WaitReadable() const { return Buffered() || Wait(POLLIN, read_deadline_); }

  bool is_readable() const override { return WaitReadable(); }
  bool is_writable() const override {
    if (!Wait(POLLOUT, Clock::now() + write_timeout_)) return false;
    // Like httplib: a peer that has closed is not writable.
    char byte;
    const ssize_t n = ::recv(fd_, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
    return !(n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK));
  }
  // Buffered like httplib's SocketStream: its line reader asks for one byte at a time, and
  // what is left after a request's headers must leave the socket (a peer that has sent
  // everything and half-closed then reads as gone, which ends its streams).
  ssize_t read(char* ptr, size_t size) override {
    if (buffer_begin_ == buffer_end_) {
      if (!WaitReadable()) return -1;
      ssize_t n;
      do {
        n = ::recv(fd_, buffer_, sizeof(buffer_), MSG_DONTWAIT);
      } while (n < 0 && errno == EINTR);
      if (n <= 0) return n;
      buffer_begin_ = 0;
      buffer_end_ = static_cast<size_t>(n);
    }
    const size_t n = std::min(size, buffer_end_ - buffer_begin_);
    std::copy_n(buffer_ + buffer_begin_, n, ptr);
    buffer_begin_ += n;
    return static_cast<ssize_t>(n);
  }
  // A request already in the buffer (pipelined after the previous one) counts as readable.
  bool Buffered() const { return buffer_begin_ != buffer_end_; }
  ssize_t write(const char* ptr, size_t size) override {
    // As httplib's stream: a peer that has closed its side ends the response (and with it
    // a live stream nobody will ask to end).
    if (!is_writable()) return -1;
    for (;;) {
      const ssize_t n = ::send(fd_, ptr, size, MSG_NOSIGNAL);
      if (n >= 0 || errno != EINTR) return n;
    }
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t len = sizeof(addr);
    if (::getpeername(fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
      AddressOf(addr, ip, port);
    }
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t len = sizeof(addr);
    if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
      AddressOf(addr, ip, port);
    }
  }
  socket_t socket() const override { return fd_; }

 private:
  bool Wait(short events, Clock::time_point deadline) const {
    for (;;) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return false;
      pollfd p{fd_, events, 0};
      const int rc = ::poll(&p, 1, static_cast<int>(std::min<int64_t>(left, 1000 * 60)));
      if (rc > 0) return true;  // ready, or an error/hangup the next call reports
      if (rc < 0 && errno != EINTR) return false;
    }
  }

  const int fd_;
  const std::chrono::milliseconds write_timeout_;
  Clock::time_point read_deadline_ = Clock::now();
  char buffer_[4096];
  size_t buffer_begin_ = 0;
  size_t buffer_end_ = 0;
};

// The connection this thread is serving (GuardedServer::HeadersComplete & co.).
struct CurrentConnection {
  ConnectionTable* table = nullptr;
  uint64_t id = 0;
  DeadlineStream* stream = nullptr;
  std::chrono::milliseconds body_timeout{0};
  bool close_after_response = false;
};
thread_local CurrentConnection current;

void Refuse(int fd) {
  static const std::string body =
      R"({"api_version":1,"error":"unavailable","message":"too many connections from this address; try again later"})";
  const std::string response =
      "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
      "X-Mirrorscan-Api-Version: 1\r\nRetry-After: 1\r\nConnection: close\r\nContent-Length: " +
      std::to_string(body.size()) + "\r\n\r\n" + body;
  // Never blocks: a client that does not read its refusal just does not get it.
  (void)!::send(fd, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

// A refused request's body may still be on its way: closing with unread bytes sends a
// reset, which makes the client's TCP drop the refusal it has not read yet. So the
// refusal is sent, the write side closed, and what arrives is discarded (never kept) for
// a moment first.
void LingeringClose(int fd) {
  ::shutdown(fd, SHUT_WR);
  const auto deadline = Clock::now() + std::chrono::milliseconds(1000);
  size_t discarded = 0;
  char buffer[16384];
  while (discarded < (16u << 20)) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) break;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left)) <= 0) break;
    const ssize_t n = ::recv(fd, buffer, sizeof(buffer), MSG_DONTWAIT);
    if (n <= 0 && !(n < 0 && errno == EINTR)) break;
    if (n > 0) discarded += static_cast<size_t>(n);
  }
}

}  // namespace

void ConnectionLimits::Validate() const {
  if (per_client < 1) throw std::invalid_argument("connection limits: per_client must be >= 1");
  if (total < per_client)
    throw std::invalid_argument("connection limits: total must be >= per_client");
  if (header_timeout.count() <= 0 || body_timeout.count() <= 0 || write_timeout.count() <= 0) {
    throw std::invalid_argument("connection limits: timeouts must be positive");
  }
  if (max_requests_per_connection < 1) {
    throw std::invalid_argument("connection limits: max_requests_per_connection must be >= 1");
  }
}

ConnectionTable::Admission ConnectionTable::Admit(const std::string& client, int fd, uint64_t& id) {
  std::lock_guard lock(mutex_);
  if (stopping_) return Admission::kStopping;
  if (per_client_[client] >= limits_.per_client) {
    ++refused_;
    return Admission::kClientFull;
  }
  if (static_cast<int>(entries_.size()) >= limits_.total) {
    // Make room: close an idle connection of the client holding the most, the one that
    // has waited longest among them, so a client with few connections (the one asking
    // for /status) is the last to lose one. Its own thread sees the shutdown and
    // releases it; until then the count is one over.
    auto oldest = entries_.end();
    int oldest_share = 0;
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (!it->second.idle || it->second.fd < 0) continue;
      const int share = per_client_[it->second.client];
      if (oldest == entries_.end() || share > oldest_share ||
          (share == oldest_share && it->second.idle_since < oldest->second.idle_since)) {
        oldest = it;
        oldest_share = share;
      }
    }
    if (oldest == entries_.end()) {
      ++refused_;
      return Admission::kClientFull;
    }
    ::shutdown(oldest->second.fd, SHUT_RDWR);
    oldest->second.fd = -1;  // not picked twice
    ++evicted_;
  }
  id = next_id_++;
  entries_[id] = Entry{client, fd, true, Clock::now()};
  ++per_client_[client];
  return Admission::kAdmitted;
}

void ConnectionTable::SetIdle(uint64_t id, bool idle) {
  std::lock_guard lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return;
  if (idle && !it->second.idle) it->second.idle_since = Clock::now();
  it->second.idle = idle;
}

void ConnectionTable::Release(uint64_t id) {
  std::lock_guard lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return;
  const auto client = per_client_.find(it->second.client);
  if (client != per_client_.end() && --client->second <= 0) per_client_.erase(client);
  entries_.erase(it);
}

void ConnectionTable::ShutdownAll() {
  std::lock_guard lock(mutex_);
  stopping_ = true;
  for (auto& [id, entry] : entries_) {
    if (entry.fd >= 0) ::shutdown(entry.fd, SHUT_RDWR);
    entry.fd = -1;
  }
}

int ConnectionTable::count() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(entries_.size());
}

int ConnectionTable::count_for(const std::string& client) const {
  std::lock_guard lock(mutex_);
  const auto it = per_client_.find(client);
  return it == per_client_.end() ? 0 : it->second;
}

uint64_t ConnectionTable::evicted() const {
  std::lock_guard lock(mutex_);
  return evicted_;
}

uint64_t ConnectionTable::refused() const {
  std::lock_guard lock(mutex_);
  return refused_;
}

GuardedServer::GuardedServer(const ConnectionLimits& limits) : limits_(limits), table_(limits) {
  limits_.Validate();
  // Refusals take a thread for a moment; admitted connections never wait for one.
  const size_t threads = static_cast<size_t>(limits_.total) + 4;
  new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  set_keep_alive_max_count(limits_.max_requests_per_connection);
  const auto seconds = [](std::chrono::milliseconds ms) {
    return std::max<time_t>(1, static_cast<time_t>((ms.count() + 999) / 1000));
  };
  // httplib puts these on the socket too (SO_RCVTIMEO/SO_SNDTIMEO); our stream polls first.
  set_read_timeout(seconds(limits_.body_timeout), 0);
  set_write_timeout(seconds(limits_.write_timeout), 0);
  set_keep_alive_timeout(seconds(limits_.header_timeout));
}

void GuardedServer::WidenBacklog(int backlog) {
  // httplib listens with a backlog of 5: clients reconnecting in a burst overflow it, and
  // a dropped SYN costs the next client a 1 s retransmission. listen() again resizes it.
  ::listen(svr_sock_, backlog);
}

void GuardedServer::HeadersComplete() {
  if (current.table == nullptr) return;
  current.table->SetIdle(current.id, false);
  current.stream->set_read_deadline(Clock::now() + current.body_timeout);
}

void GuardedServer::CloseAfterResponse() { current.close_after_response = true; }

bool GuardedServer::ClosingAfterResponse() { return current.close_after_response; }

bool GuardedServer::process_and_close_socket(socket_t sock) {
  std::string client;
  int port = 0;
  {
    sockaddr_storage addr{};
    socklen_t len = sizeof(addr);
    if (::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
      AddressOf(addr, client, port);
    }
  }
  uint64_t id = 0;
  const ConnectionTable::Admission admission = table_.Admit(client, sock, id);
  bool ret = false;
  if (admission == ConnectionTable::Admission::kAdmitted) {
    DeadlineStream stream(sock, limits_.write_timeout);
    current = CurrentConnection{&table_, id, &stream, limits_.body_timeout, false};
    for (size_t left = limits_.max_requests_per_connection; left > 0; --left) {
      table_.SetIdle(id, true);
      stream.set_read_deadline(Clock::now() + limits_.header_timeout);
      if (!stream.WaitReadable()) break;
      bool connection_closed = false;
      current.close_after_response = false;
      ret = process_request(stream, left == 1, connection_closed, nullptr);
      if (current.close_after_response) {
        LingeringClose(sock);
        break;
      }
      if (!ret || connection_closed) break;
    }
    current = CurrentConnection{};
    table_.Release(id);
  } else if (admission == ConnectionTable::Admission::kClientFull) {
    Refuse(sock);
  }
  ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
  return ret;
}

FailedTokenLimiter::FailedTokenLimiter(Options options, std::function<Clock::time_point()> now)
    : options_(options), now_(now ? std::move(now) : [] { return Clock::now(); }) {}

void FailedTokenLimiter::Refill(Bucket& bucket, Clock::time_point now) const {
  const double elapsed = std::chrono::duration<double, std::milli>(now - bucket.updated).count();
  bucket.tokens = std::min<double>(
      options_.burst, bucket.tokens + elapsed / static_cast<double>(options_.refill.count()));
  bucket.updated = now;
}

int64_t FailedTokenLimiter::RetryAfterMs(const std::string& client) {
  std::lock_guard lock(mutex_);
  const auto it = buckets_.find(client);
  if (it == buckets_.end()) return 0;
  Refill(it->second, now_());
  if (it->second.tokens >= 1.0) return 0;
  return static_cast<int64_t>((1.0 - it->second.tokens) *
                              static_cast<double>(options_.refill.count())) +
         1;
}

void FailedTokenLimiter::RecordFailure(const std::string& client) {
  std::lock_guard lock(mutex_);
  const Clock::time_point now = now_();
  auto it = buckets_.find(client);
  if (it == buckets_.end()) {
    if (buckets_.size() >= options_.max_clients) {
      // Forget the address closest to a full bucket (least to remember).
      auto fullest = buckets_.begin();
      for (auto b = buckets_.begin(); b != buckets_.end(); ++b) {
        Refill(b->second, now);
        if (b->second.tokens > fullest->second.tokens) fullest = b;
      }
      buckets_.erase(fullest);
    }
    it = buckets_.emplace(client, Bucket{static_cast<double>(options_.burst), now}).first;
  }
  Refill(it->second, now);
  it->second.tokens = std::max(0.0, it->second.tokens - 1.0);
}

}  // namespace mirrorscan::service

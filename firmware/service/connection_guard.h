#pragma once

// What keeps the device API served under hostile or broken clients (docs/device-api.md,
// "Limits"): cpp-httplib 0.11 gives every connection a worker thread for as long as the
// client keeps it open and has no deadline on a request as a whole, so a few idle or
// trickling sockets starve it. GuardedServer (guarded_server.h) replaces its loop:
//  - admission when the connection is taken: at most `per_client` connections per client
//    address (more get an immediate 503 and are closed) and `total` in all; at the total
//    a connection that is only waiting for a request (idle keep-alive, or headers not
//    complete yet) is closed to make room: the longest-waiting one of the client holding
//    the most, so a new client is always served;
//  - a deadline for the wait and the request line + headers together (`header_timeout`),
//    then one for the body (`body_timeout`), instead of httplib's per-read timeout that a
//    byte every few seconds resets;
//  - a worker thread for every admitted connection (the pool has `total` + a reserve for
//    refusals), so nothing waits in a queue behind a held connection.
// FailedTokenLimiter rate-limits wrong bearer tokens per client address.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>

namespace mirrorscan::service {

struct ConnectionLimits {
  int per_client = 8;                              // connections from one address at once
  int total = 32;                                  // connections at once (also the worker threads)
  std::chrono::milliseconds header_timeout{5000};  // wait + request line + headers
  std::chrono::milliseconds body_timeout{10000};   // the whole request body
  std::chrono::milliseconds write_timeout{10000};  // one write of the response
  size_t max_requests_per_connection = 100;
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

// The connections being served, by client address; thread-safe. A connection is "idle"
// while it waits for or reads a request's headers: only idle ones are evicted.
class ConnectionTable {
 public:
  using Clock = std::chrono::steady_clock;
  explicit ConnectionTable(const ConnectionLimits& limits) : limits_(limits) {}

  enum class Admission { kAdmitted, kClientFull, kStopping };
  // On kAdmitted `id` names the connection for the calls below. When the total is
  // reached, an idle connection's socket is shut down (its thread then ends it): the
  // longest idle of the client with the most connections.
  Admission Admit(const std::string& client, int fd, uint64_t& id);
  void SetIdle(uint64_t id, bool idle);
  void Release(uint64_t id);
  // Refuses new connections and shuts every socket down (Stop).
  void ShutdownAll();

  int count() const;
  int count_for(const std::string& client) const;
  uint64_t evicted() const;
  uint64_t refused() const;

 private:
  struct Entry {
    std::string client;
    int fd = -1;
    bool idle = true;
    Clock::time_point idle_since;
  };
  const ConnectionLimits limits_;
  mutable std::mutex mutex_;
  std::map<uint64_t, Entry> entries_;
  std::map<std::string, int> per_client_;
  uint64_t next_id_ = 1;
  uint64_t evicted_ = 0;
  uint64_t refused_ = 0;
  bool stopping_ = false;
};

// Wrong tokens per client address: a bucket of `burst` failures refilled at one per
// `refill`; an empty bucket refuses the address (429) without comparing its token, so
// guessing runs at most one try per `refill`.
class FailedTokenLimiter {
 public:
  using Clock = std::chrono::steady_clock;
  struct Options {
    int burst = 10;
    std::chrono::milliseconds refill{1000};
    size_t max_clients = 4096;  // addresses remembered; the fullest buckets go first
  };
  FailedTokenLimiter() : FailedTokenLimiter(Options{}) {}
  explicit FailedTokenLimiter(Options options, std::function<Clock::time_point()> now = {});

  // 0 when `client` may try a token now, else the milliseconds until it may.
  int64_t RetryAfterMs(const std::string& client);
  void RecordFailure(const std::string& client);

 private:
  struct Bucket {
    double tokens;
    Clock::time_point updated;
  };
  void Refill(Bucket& bucket, Clock::time_point now) const;
  const Options options_;
  const std::function<Clock::time_point()> now_;
  std::mutex mutex_;
  std::map<std::string, Bucket> buckets_;
};

}  // namespace mirrorscan::service

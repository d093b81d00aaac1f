#pragma once

// The device API's HTTP server: cpp-httplib's, with the per-connection loop replaced
// (connection_guard.h says why). Only firmware/service's sources include this header.

#include <httplib.h>

#include "firmware/service/connection_guard.h"

namespace mirrorscan::service {

class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(const ConnectionLimits& limits);
  ConnectionTable& connections() { return table_; }
  const ConnectionLimits& limits() const { return limits_; }
  // After binding: a listen backlog of `backlog` instead of httplib's 5.
  void WidenBacklog(int backlog);

  // For handlers on the connection's own thread: the headers are in, so the body deadline
  // starts now and the connection is no longer idle (pre-routing calls this).
  static void HeadersComplete();
  // The response to this request ends the connection (a refused request whose body was
  // never read must not be parsed as the next request).
  static void CloseAfterResponse();
  static bool ClosingAfterResponse();

 private:
  bool process_and_close_socket(socket_t sock) override;
  const ConnectionLimits limits_;
  ConnectionTable table_;
};

}  // namespace mirrorscan::service

#pragma once
// Talking to a server on loopback the way hostile or careful clients do: raw sockets from
// chosen 127/8 addresses, and plain HTTP/1.1 requests with nothing of a client library in
// between.

#include <chrono>
#include <string>

namespace mirrorscan::test_support {

// A loopback TCP port nobody listens on right now.
int FreeLoopbackPort();

// A socket connected to 127.0.0.1:port from `source` (any 127/8 address is loopback on
// Linux, so a test can be several clients); sends and receives time out after `timeout`.
// -1 on failure. The caller closes it.
int ConnectLoopback(int port, const char* source = "127.0.0.1",
                    std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));

// Sends all of `bytes`; false once the server has closed (EPIPE/ECONNRESET) or a send
// times out.
bool SendAll(int fd, const std::string& bytes);

// What the server sends until it closes, a receive times out, or `limit` bytes came.
std::string ReceiveAll(int fd, size_t limit = 1 << 20);

// `request` as raw bytes to 127.0.0.1:port, then the write side shut; whatever comes back
// within a short timeout (300 ms without a byte).
std::string RawExchange(int port, const std::string& request);

struct HttpReply {
  int status = 0;  // 0: no answer
  std::string headers;
  std::string body;
};

// One request with Connection: close (and the bearer token, and a JSON body, when given);
// the whole reply, up to 64 MiB.
HttpReply HttpRequest(int port, const std::string& method, const std::string& path,
                      const std::string& token = "", const std::string& body = "");

}  // namespace mirrorscan::test_support

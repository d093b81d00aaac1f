// The HTTP pieces the device API's handlers share (api_server.cc, results_api.cc): the
// refusal a handler throws, JSON replies, the scan id from the route, file reads.
// Internal to firmware/service.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <stdexcept>
#include <string>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace mirrorscan::service::internal {

inline constexpr size_t kReadChunk = 64 * 1024;

// A handler's refusal: the status and the one sentence the client sees.
class HttpError : public std::runtime_error {
 public:
  HttpError(int status, const std::string& message)
      : std::runtime_error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

// Sets the API version header unless the handler set it.
void SetVersionHeader(httplib::Response& res);
// A JSON reply; an object gets "api_version".
void SendJson(httplib::Response& res, int status, nlohmann::json body);
// The API's error object: the status's code name and `message`.
void SendError(httplib::Response& res, int status, const std::string& message);

// The id from the route, checked before anything else sees it.
std::string ScanIdFrom(const httplib::Request& req);

// Owns an open file descriptor; closes it when the last reply that reads it is done.
struct FileDescriptor {
  explicit FileDescriptor(int value) : fd(value) {}
  ~FileDescriptor() {
    if (fd >= 0) ::close(fd);
  }
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  int fd;
};

// pread, retried on EINTR.
ssize_t ReadAt(int fd, char* buffer, size_t size, uint64_t offset);

}  // namespace mirrorscan::service::internal

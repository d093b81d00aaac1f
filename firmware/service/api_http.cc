#include "firmware/service/api_http.h"

#include <cerrno>

#include "common/protocol/protocol.h"

namespace mirrorscan::service::internal {

void SetVersionHeader(httplib::Response& res) {
  if (!res.has_header(std::string(protocol::kApiVersionHeader).c_str())) {
    res.set_header(std::string(protocol::kApiVersionHeader).c_str(),
                   std::to_string(protocol::kApiVersion));
  }
}

void SendJson(httplib::Response& res, int status, nlohmann::json body) {
  if (body.is_object() && !body.contains("api_version"))
    body["api_version"] = protocol::kApiVersion;
  res.status = status;
  SetVersionHeader(res);
  res.set_content(body.dump(), "application/json");
}

void SendError(httplib::Response& res, int status, const std::string& message) {
  SendJson(res, status, protocol::ApiError{std::string(protocol::ErrorCode(status)), message});
}

std::string ScanIdFrom(const httplib::Request& req) {
  const std::string id = req.matches[1];
  if (!protocol::IsValidScanId(id)) {
    throw HttpError(400, "not a scan id (expected YYYYMMDDTHHMMSSZ-NNNN)");
  }
  return id;
}

ssize_t ReadAt(int fd, char* buffer, size_t size, uint64_t offset) {
  for (;;) {
    const ssize_t n = ::pread(fd, buffer, size, static_cast<off_t>(offset));
    if (n >= 0 || errno != EINTR) return n;
  }
}

}  // namespace mirrorscan::service::internal

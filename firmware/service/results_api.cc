// The device API's results: what the host puts for a scan (mesh, previews, measurements,
// summary) and the device's page shows (docs/device-api.md).
#include "firmware/service/api_server.h"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "common/protocol/protocol.h"
#include "firmware/service/api_http.h"
#include "firmware/service/guarded_server.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;
using internal::FileDescriptor;
using internal::HttpError;
using internal::kReadChunk;
using internal::ReadAt;
using internal::ScanIdFrom;
using internal::SendJson;
using internal::SetVersionHeader;
using nlohmann::json;

std::string FormatUtc(fs::file_time_type time) {
  const auto system = std::chrono::time_point_cast<std::chrono::system_clock::duration>(
      time - fs::file_time_type::clock::now() + std::chrono::system_clock::now());
  const std::time_t t = std::chrono::system_clock::to_time_t(system);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

const protocol::ResultKind& ResultKindFrom(const httplib::Request& req) {
  const protocol::ResultKind* kind = protocol::FindResultKind(req.matches[2].str());
  if (kind == nullptr) {
    std::string names;
    for (const protocol::ResultKind& k : protocol::ResultKinds()) {
      names += (names.empty() ? "" : ", ") + std::string(k.name);
    }
    throw HttpError(404,
                    "no result named \"" + req.matches[2].str() + "\" (results: " + names + ")");
  }
  return *kind;
}

// What the page shows must be what the name says: a PNG, a PLY, a JSON object.
void CheckResultContent(const protocol::ResultKind& kind, const std::string& head,
                        const std::string* whole) {
  const std::string name(kind.name);
  auto ends_with = [&](std::string_view suffix) {
    return name.size() >= suffix.size() &&
           name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  if (ends_with(".png") && head.rfind("\x89PNG\r\n\x1a\n", 0) != 0) {
    throw HttpError(400, name + ": not a PNG image");
  }
  if (ends_with(".ply") && head.rfind("ply\n", 0) != 0 && head.rfind("ply\r\n", 0) != 0) {
    throw HttpError(400, name + ": not a PLY file (no \"ply\" line)");
  }
  if (ends_with(".json") && whole != nullptr) {
    const json parsed = json::parse(*whole, nullptr, false);
    if (parsed.is_discarded() || !parsed.is_object()) {
      throw HttpError(400, name + ": not a JSON object");
    }
  }
}

}  // namespace

void ApiServer::HandleListResults(const Request& req, Response& res) {
  const std::string id = ScanIdFrom(req);
  json results = json::array();
  for (const store::StoredResult& r : store_.Results(id)) {
    results.push_back(protocol::ResultInfo{r.name, r.bytes, FormatUtc(r.modified)});
  }
  SendJson(res, 200, {{"id", id}, {"results", results}});
}

void ApiServer::HandleGetResult(const Request& req, Response& res) {
  const std::string id = ScanIdFrom(req);
  const protocol::ResultKind& kind = ResultKindFrom(req);
  const fs::path path = store_.ResultPath(id, std::string(kind.name));
  // The descriptor keeps the bytes of this version even if an upload replaces the file.
  auto file = std::make_shared<FileDescriptor>(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (file->fd < 0) throw HttpError(404, "scan " + id + " has no result " + std::string(kind.name));
  struct stat info {};
  if (::fstat(file->fd, &info) != 0) throw HttpError(500, "cannot read " + std::string(kind.name));
  const uint64_t size = static_cast<uint64_t>(info.st_size);
  res.status = 200;
  res.set_header("Cache-Control", "no-store");  // a body scan: never in a shared cache
  res.set_header("Content-Disposition",
                 "attachment; filename=\"" + id + "-" + std::string(kind.name) + "\"");
  SetVersionHeader(res);
  if (size == 0) {
    res.set_content("", std::string(kind.content_type));
    return;
  }
  res.set_content_provider(size, std::string(kind.content_type),
                           [file](size_t offset, size_t length, httplib::DataSink& sink) {
                             std::vector<char> buffer(std::min(length, kReadChunk));
                             const ssize_t n =
                                 ReadAt(file->fd, buffer.data(), buffer.size(), offset);
                             if (n <= 0) return false;
                             return sink.write(buffer.data(), static_cast<size_t>(n));
                           });
}

void ApiServer::HandleEmptyResult(const Request& req, Response&) {
  ScanIdFrom(req);
  ResultKindFrom(req);
  throw HttpError(400, "request body: expected the result's bytes");
}

void ApiServer::HandlePutResult(const Request& req, Response& res,
                                const httplib::ContentReader& read) {
  const std::string id = ScanIdFrom(req);
  const protocol::ResultKind& kind = ResultKindFrom(req);
  const std::string name(kind.name);
  std::unique_ptr<store::ResultUpload> upload = store_.BeginResult(id, name);
  constexpr size_t kHead = 16;
  const bool is_json = name.size() > 5 && name.compare(name.size() - 5, 5, ".json") == 0;
  std::string head;   // the first bytes, for the content check
  std::string whole;  // JSON results are parsed whole (at most 1 MiB)
  bool too_large = false;
  std::string store_error;
  const bool complete = read([&](const char* data, size_t length) {
    if (upload->bytes() + length > kind.max_bytes) {
      too_large = true;
      return false;
    }
    if (head.size() < kHead) head.append(data, std::min(length, kHead - head.size()));
    if (is_json) whole.append(data, length);
    try {
      upload->Append(data, length);
    } catch (const store::StoreError& e) {
      store_error = e.what();
      return false;
    }
    return true;
  });
  if (!complete) {
    GuardedServer::CloseAfterResponse();  // the rest of the body is never read
    if (!store_error.empty()) throw HttpError(500, store_error);
    if (too_large) {
      throw HttpError(413,
                      name + " too large (limit " + std::to_string(kind.max_bytes) + " bytes)");
    }
    throw HttpError(400, "request body: incomplete or malformed chunked encoding");
  }
  if (upload->bytes() == 0) throw HttpError(400, "request body: expected the result's bytes");
  CheckResultContent(kind, head, is_json ? &whole : nullptr);
  upload->Commit();
  SendJson(res, 200, {{"id", id}, {"name", name}, {"bytes", upload->bytes()}});
}

}  // namespace mirrorscan::service

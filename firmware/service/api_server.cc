#include "firmware/service/api_server.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <condition_variable>
#include <ctime>
#include <deque>
#include <functional>
#include <regex>
#include <stdexcept>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"
#include "common/peaks/peaks.h"
#include "common/protocol/protocol.h"
#include "common/protocol/sha256.h"
#include "firmware/service/api_http.h"
#include "firmware/service/guarded_server.h"
#include "firmware/service/preview_image.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;
using internal::FileDescriptor;
using internal::HttpError;
using internal::kReadChunk;
using internal::ReadAt;
using internal::ScanIdFrom;
using internal::SendError;
using internal::SendJson;
using internal::SetVersionHeader;
using nlohmann::json;

constexpr size_t kMaxQueuedEvents = 64;  // per SSE client; the oldest go first

int StoreErrorStatus(store::StoreError::Kind kind) {
  switch (kind) {
    case store::StoreError::Kind::kInvalidId:
      return 400;
    case store::StoreError::Kind::kNotFound:
      return 404;
    case store::StoreError::Kind::kBusy:
      return 409;
    case store::StoreError::Kind::kInvalidArgument:
      return 400;
    case store::StoreError::Kind::kIo:
      return 500;
  }
  return 500;
}

int ControlErrorStatus(scan::ScanControlError::Kind kind) {
  switch (kind) {
    case scan::ScanControlError::Kind::kBusy:
      return 409;
    case scan::ScanControlError::Kind::kInvalidArgument:
      return 400;
    case scan::ScanControlError::Kind::kUnavailable:
      return 503;
  }
  return 500;
}

protocol::ScanProgress ToProgress(const scan::ScanStatus& s) {
  protocol::ScanProgress p;
  p.state = std::string(scan::SequencerStateName(s.state));
  p.scan_id = s.scan_id;
  p.progress = s.progress;
  p.position_mm = s.position_mm;
  p.frames = s.frames;
  p.peaks = s.peaks;
  p.dropped = s.dropped;
  p.reason = s.reason;
  return p;
}

protocol::ScanSummary ToSummary(const store::ScanInfo& info) {
  protocol::ScanSummary s;
  s.id = info.id;
  s.state = std::string(store::ScanStateName(info.state));
  s.reason = info.reason;
  s.created = info.created;
  s.frames = info.frames;
  s.peaks = info.peaks;
  s.bytes = info.bytes;
  s.header = info.header;
  s.footer = info.footer;
  return s;
}

std::optional<uint64_t> ParseUnsigned(const std::string& text) {
  if (text.empty() || text.size() > 19 ||
      text.find_first_not_of("0123456789") != std::string::npos) {
    return std::nullopt;
  }
  return std::stoull(text);
}

struct ByteRange {
  uint64_t first = 0;
  uint64_t last = 0;  // inclusive
};

// One range of "bytes=N-", "bytes=N-M" or "bytes=-S" against a file of `size` bytes;
// nullopt when it is malformed, multiple or unsatisfiable.
std::optional<ByteRange> ParseRange(const std::string& header, uint64_t size) {
  constexpr std::string_view kPrefix = "bytes=";
  if (header.rfind(kPrefix, 0) != 0 || size == 0) return std::nullopt;
  const std::string spec = header.substr(kPrefix.size());
  const size_t dash = spec.find('-');
  if (dash == std::string::npos || spec.find(',') != std::string::npos) return std::nullopt;
  const auto first = ParseUnsigned(spec.substr(0, dash));
  const auto last = ParseUnsigned(spec.substr(dash + 1));
  if (!first && !last) return std::nullopt;
  if (!first) {  // a suffix: the last S bytes
    if (*last == 0) return std::nullopt;
    return ByteRange{*last >= size ? 0 : size - *last, size - 1};
  }
  if (*first >= size) return std::nullopt;
  if (last && *last < *first) return std::nullopt;
  return ByteRange{*first, last ? std::min(*last, size - 1) : size - 1};
}

std::string FormatEvent(const scan::ScanEvent& event) {
  protocol::ScanEventMessage message;
  message.type = event.type == scan::ScanEvent::Type::kState ? "state" : "progress";
  message.scan = ToProgress(event.status);
  return "event: " + message.type + "\ndata: " + json(message).dump() + "\n\n";
}

// A body follows the headers (httplib's own test is not in its public header).
bool HasBody(const httplib::Request& req) {
  if (req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos) return true;
  const std::string length = req.get_header_value("Content-Length");
  return !length.empty() && length.find_first_not_of('0') != std::string::npos;
}

json ParseBodyObject(const httplib::Request& req, bool allow_empty) {
  if (req.body.empty()) {
    if (allow_empty) return json::object();
    throw HttpError(400, "request body: expected a JSON object");
  }
  json body;
  try {
    body = JsonReader::ParseText(req.body, "request body");
  } catch (const ConfigError& e) {
    throw HttpError(400, e.what());
  }
  if (!body.is_object()) throw HttpError(400, "request body: expected a JSON object");
  return body;
}

}  // namespace

ApiServer::ApiServer(store::ScanStore& store, scan::ScanControl& control,
                     const board::BoardConfig& board, CalibrationStore& calibration,
                     std::string token, ApiServerOptions options)
    : store_(store),
      control_(control),
      board_(board),
      calibration_(calibration),
      token_(std::move(token)),
      options_(std::move(options)),
      server_(std::make_unique<GuardedServer>(options_.connections)),
      failed_tokens_(options_.failed_tokens) {
  if (!board::IsValidServiceToken(token_)) {
    throw std::invalid_argument(std::string("API token: expected ") + board::kServiceTokenRule);
  }
  if (options_.max_streams < 1 || options_.connections.total <= options_.max_streams) {
    throw std::invalid_argument("ApiServerOptions: need 1 <= max_streams < connections.total");
  }
  Route();
}

ApiServer::~ApiServer() { Stop(); }

int ApiServer::Start(const std::string& listen) {
  if (thread_.joinable()) throw std::logic_error("ApiServer::Start called twice");
  const size_t colon = listen.rfind(':');
  const auto port =
      colon == std::string::npos ? std::nullopt : ParseUnsigned(listen.substr(colon + 1));
  if (colon == 0 || !port || *port > 65535) {
    throw std::runtime_error("listen address " + listen + ": expected host:port");
  }
  std::string host = listen.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  int bound = static_cast<int>(*port);
  if (bound == 0) {
    bound = server_->bind_to_any_port(host);
    if (bound < 0) throw std::runtime_error("cannot listen on " + listen);
  } else if (!server_->bind_to_port(host, bound)) {
    throw std::runtime_error("cannot listen on " + listen + " (address in use or not local?)");
  }
  server_->WidenBacklog(128);
  thread_ = std::thread([this] {
    server_->listen_after_bind();
    listen_ended_ = true;
  });
  // httplib's stop() is a no-op until the accept loop runs; wait for it so Stop always works.
  while (!server_->is_running() && !listen_ended_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return bound;
}

void ApiServer::Stop() {
  stopping_ = true;
  server_->connections().ShutdownAll();  // idle keep-alive waits end now, not at their deadline
  server_->stop();
  if (thread_.joinable()) thread_.join();
}

void ApiServer::Route() {
  GuardedServer& s = *server_;
  // httplib's own check against Content-Length, at the largest limit of any route; the
  // per-route limit (BodyLimit) is applied before it, in the pre-routing handler.
  size_t largest = options_.max_body_bytes;
  for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
    largest = std::max<size_t>(largest, kind.max_bytes);
  }
  s.set_payload_max_length(largest);

  // Runs once the headers are in and before any byte of a body is read: the token, the
  // failed-token limit and the declared size are checked here, so a client without the
  // token never gets its body read at all.
  s.set_pre_routing_handler([this](const Request& req, Response& res) {
    GuardedServer::HeadersComplete();
    // cpp-httplib 0.11 would cut every response body (even JSON errors) by a Range
    // header after the handler ran; only the archive honours Range, and does so itself.
    const_cast<Request&>(req).ranges.clear();
    // RFC 9112 6.3: a request with neither Content-Length nor Transfer-Encoding has no
    // body (`curl -X POST` without -d); httplib 0.11 would read one until the socket
    // closes.
    if (!req.has_header("Content-Length") && !req.has_header("Transfer-Encoding")) {
      const_cast<Request&>(req).headers.emplace("Content-Length", "0");
    }
    if (!Authorize(req, res) || !BodyFits(req, res)) {
      if (HasBody(req)) GuardedServer::CloseAfterResponse();
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // "Expect: 100-continue": the same checks before the client is told to send the body.
  s.set_expect_100_continue_handler([this](const Request& req, Response& res) {
    GuardedServer::HeadersComplete();
    if (!Authorize(req, res) || !BodyFits(req, res)) {
      GuardedServer::CloseAfterResponse();
      return res.status;
    }
    return 100;
  });
  // Errors httplib answers itself (no route, body too large, bad request line) get the
  // same JSON body as ours.
  s.set_error_handler(httplib::Server::HandlerWithResponse([this](const Request& req,
                                                                  Response& res) {
    if (!res.body.empty() || res.content_provider_ || res.status < 400) {
      return httplib::Server::HandlerResponse::Unhandled;
    }
    if (res.status == 416) {
      // httplib refuses a Range it cannot parse before routing; the archive's size is
      // still owed (RFC 9110 15.5.17).
      static const std::regex kArchive(std::string(protocol::kApiPrefix) +
                                       "/scans/([^/]+)/archive");
      std::smatch match;
      if (std::regex_match(req.path, match, kArchive) && protocol::IsValidScanId(match[1].str()) &&
          (!NeedsToken(req) || req.has_header("Authorization"))) {
        try {
          res.set_header("Content-Range",
                         "bytes */" + std::to_string(fs::file_size(store_.Path(match[1].str()))));
        } catch (const std::exception&) {
          // no such scan: the 416 stands without a size
        }
      }
    }
    const std::string message = res.status == 404   ? "no such endpoint"
                                : res.status == 413 ? "request body too large"
                                : res.status == 416 ? "malformed Range header"
                                                    : "malformed request";
    SendError(res, res.status, message);
    return httplib::Server::HandlerResponse::Handled;
  }));
  s.set_post_routing_handler([](const Request&, Response& res) {
    SetVersionHeader(res);
    if (GuardedServer::ClosingAfterResponse()) {
      res.headers.erase("Keep-Alive");
      res.headers.erase("Connection");
      res.set_header("Connection", "close");
    }
  });

  using Member = void (ApiServer::*)(const Request&, Response&);
  const auto wrap = [this](Member member) {
    return [this, member](const Request& req, Response& res) {
      try {
        (this->*member)(req, res);
      } catch (const HttpError& e) {
        SendError(res, e.status(), e.what());
      } catch (const store::StoreError& e) {
        SendError(res, StoreErrorStatus(e.kind()), e.what());
      } catch (const scan::ScanControlError& e) {
        SendError(res, ControlErrorStatus(e.kind()), e.what());
      } catch (const ConfigError& e) {
        SendError(res, 400, e.what());
      } catch (const std::exception& e) {
        SendError(res, 500, e.what());
      }
    };
  };
  // Bodies are read here, not by httplib: its own reader has no limit on chunked bodies.
  const auto with_body = [this, wrap](Member member) {
    return [this, handler = wrap(member)](const Request& req, Response& res,
                                          const httplib::ContentReader& read) {
      std::string body;
      bool too_large = false;
      const bool complete = read([&](const char* data, size_t length) {
        if (body.size() + length > options_.max_body_bytes) {
          too_large = true;
          return false;
        }
        body.append(data, length);
        return true;
      });
      if (!complete) {
        GuardedServer::CloseAfterResponse();  // the rest of the body is never read
        SendError(res, too_large ? 413 : 400,
                  too_large ? "request body too large (limit " +
                                  std::to_string(options_.max_body_bytes) + " bytes)"
                            : "request body: incomplete or malformed chunked encoding");
        return;
      }
      const_cast<Request&>(req).body = std::move(body);
      handler(req, res);
    };
  };
  const std::string api(protocol::kApiPrefix);
  const std::string scan = api + "/scans/([^/]+)";
  s.Get(api + "/status", wrap(&ApiServer::HandleStatus));
  s.Get(api + "/scans", wrap(&ApiServer::HandleListScans));
  s.Post(api + "/scans", wrap(&ApiServer::HandleStartScan));
  s.Post(api + "/scans", with_body(&ApiServer::HandleStartScan));
  s.Post(api + "/scans/current/abort", wrap(&ApiServer::HandleAbort));
  s.Post(api + "/scans/current/abort", with_body(&ApiServer::HandleAbort));
  s.Get(scan, wrap(&ApiServer::HandleGetScan));
  s.Delete(scan, wrap(&ApiServer::HandleDeleteScan));
  s.Get(scan + "/archive", wrap(&ApiServer::HandleArchive));
  s.Get(api + "/events", wrap(&ApiServer::HandleEvents));
  s.Get(api + "/calibration", wrap(&ApiServer::HandleGetCalibration));
  s.Put(api + "/calibration", wrap(&ApiServer::HandlePutCalibration));
  s.Put(api + "/calibration", with_body(&ApiServer::HandlePutCalibration));
  s.Post(api + "/captures", wrap(&ApiServer::HandleCapture));
  s.Post(api + "/captures", with_body(&ApiServer::HandleCapture));
  s.Get(api + "/preview", wrap(&ApiServer::HandlePreview));
  s.Get(scan + "/results", wrap(&ApiServer::HandleListResults));
  s.Get(scan + "/results/([^/]+)", wrap(&ApiServer::HandleGetResult));
  if (!options_.web_dir.empty()) {
    if (!s.set_mount_point("/", options_.web_dir.string())) {
      throw std::invalid_argument("web page: no folder " + options_.web_dir.string());
    }
    s.set_file_request_handler([](const Request&, Response& res) {
      // The page runs only its own scripts and talks only to this device.
      res.set_header("Content-Security-Policy",
                     "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; "
                     "script-src 'self'; connect-src 'self'; frame-ancestors 'none'");
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_header("Referrer-Policy", "no-referrer");
      res.set_header("Cache-Control", "no-cache");
    });
  }
  // Without a body httplib calls the plain handler: an empty result is refused there.
  s.Put(scan + "/results/([^/]+)", wrap(&ApiServer::HandleEmptyResult));
  s.Put(scan + "/results/([^/]+)",
        [this](const Request& req, Response& res, const httplib::ContentReader& read) {
          try {
            HandlePutResult(req, res, read);
          } catch (const HttpError& e) {
            SendError(res, e.status(), e.what());
          } catch (const store::StoreError& e) {
            SendError(res, StoreErrorStatus(e.kind()), e.what());
          } catch (const std::exception& e) {
            SendError(res, 500, e.what());
          }
        });
}

bool ApiServer::NeedsToken(const Request& req) const {
  if (req.method != "GET" && req.method != "HEAD") return true;
  const std::string api = std::string(protocol::kApiPrefix) + "/";
  if (req.path.compare(0, api.size(), api) != 0) return false;  // the page's static files
  if (req.path == api + "status") return false;
  // A preview with the lasers on switches them on: never without the token.
  if (req.path == api + "preview" && req.get_param_value("lasers") == "1") return true;
  return board_.service.auth_reads;
}

bool ApiServer::Authorize(const Request& req, Response& res) {
  if (!NeedsToken(req)) return true;
  const std::string& client = req.remote_addr;
  if (const int64_t wait_ms = failed_tokens_.RetryAfterMs(client); wait_ms > 0) {
    res.set_header("Retry-After", std::to_string((wait_ms + 999) / 1000));
    SendError(res, 429,
              "too many wrong tokens from this address; retry in " +
                  std::to_string((wait_ms + 999) / 1000) + " s");
    return false;
  }
  const std::string header = req.get_header_value("Authorization");
  // RFC 9110 11.1: the scheme is case-insensitive; one or more spaces follow it.
  const size_t space = header.find(' ');
  std::string scheme = header.substr(0, space);
  std::transform(scheme.begin(), scheme.end(), scheme.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (space == std::string::npos || scheme != "bearer") {
    res.set_header("WWW-Authenticate", "Bearer realm=\"mirrorscan\"");
    SendError(res, 401, "missing bearer token (Authorization: Bearer <token>)");
    return false;
  }
  const size_t start = header.find_first_not_of(' ', space);
  const std::string_view presented =
      start == std::string::npos ? std::string_view() : std::string_view(header).substr(start);
  if (!protocol::SecretsEqual(presented, token_)) {
    failed_tokens_.RecordFailure(client);
    SendError(res, 403, "wrong bearer token");
    return false;
  }
  return true;
}

size_t ApiServer::BodyLimit(const Request& req) const {
  if (req.method != "PUT") return options_.max_body_bytes;
  static const std::regex kResult(std::string(protocol::kApiPrefix) +
                                  "/scans/[^/]+/results/([^/]+)");
  std::smatch match;
  if (!std::regex_match(req.path, match, kResult)) return options_.max_body_bytes;
  const protocol::ResultKind* kind = protocol::FindResultKind(match[1].str());
  return kind != nullptr ? kind->max_bytes : options_.max_body_bytes;
}

bool ApiServer::BodyFits(const Request& req, Response& res) const {
  if (!req.has_header("Content-Length")) return true;  // none, or chunked: read with the limit
  const auto length = ParseUnsigned(req.get_header_value("Content-Length"));
  if (!length) {
    SendError(res, 400, "Content-Length: expected a byte count");
    return false;
  }
  const size_t limit = BodyLimit(req);
  if (*length > limit) {
    SendError(res, 413,
              "request body too large (" + std::to_string(*length) + " bytes; limit " +
                  std::to_string(limit) + ")");
    return false;
  }
  return true;
}

void ApiServer::HandleStatus(const Request&, Response& res) {
  protocol::DeviceStatus status;
  status.board = board_.board;
  status.firmware_version = options_.firmware_version;
  status.calibration_sha256 = calibration_.Sha256();
  status.calibration_problem = calibration_.problem();
  for (const board::BoardCamera& camera : board_.cameras) status.cameras.push_back(camera.name);
  status.scan = ToProgress(control_.Status());
  std::error_code ec;
  const fs::space_info space = fs::space(store_.dir(), ec);
  if (!ec) {
    status.disk.total_bytes = space.capacity;
    status.disk.free_bytes = space.available;
  }
  for (const store::ScanInfo& info : store_.List()) status.disk.scans_bytes += info.bytes;
  const std::string store_problem = store_.problem();
  if (!store_problem.empty()) {
    status.disk.full = true;
    status.disk.problem = store_problem + "; delete scans to make room (DELETE /api/v1/scans/{id})";
  } else if (!ec && space.available < options_.min_free_bytes) {
    status.disk.full = true;
    status.disk.problem = "disk full: " + std::to_string(space.available >> 20) +
                          " MiB free, a scan needs " +
                          std::to_string(options_.min_free_bytes >> 20) +
                          "; delete scans to make room (DELETE /api/v1/scans/{id})";
  }
  SendJson(res, 200, status);
}

protocol::ScanSummary ApiServer::Summary(const store::ScanInfo& info) const {
  protocol::ScanSummary summary = ToSummary(info);
  try {
    for (const store::StoredResult& result : store_.Results(info.id)) {
      summary.results.push_back(result.name);
    }
  } catch (const store::StoreError&) {
    // deleted since it was listed: no results
  }
  return summary;
}

void ApiServer::HandleListScans(const Request&, Response& res) {
  json scans = json::array();
  for (const store::ScanInfo& info : store_.List()) scans.push_back(Summary(info));
  SendJson(res, 200, {{"scans", scans}});
}

void ApiServer::HandleStartScan(const Request& req, Response& res) {
  const json body = ParseBodyObject(req, true);
  if (!body.empty()) throw HttpError(400, "request body: expected {} or no body");
  const std::string id = control_.StartScan("api");
  res.set_header("Location", std::string(protocol::kApiPrefix) + "/scans/" + id);
  SendJson(res, 201, {{"id", id}});
}

void ApiServer::HandleAbort(const Request& req, Response& res) {
  const json body = ParseBodyObject(req, true);
  const JsonReader r(body, "request body");
  r.AllowOnly({"reason"});
  const std::string reason = r.String("reason", "aborted over the API");
  const scan::ScanStatus status = control_.Status();
  const bool running = status.state == scan::SequencerState::kHoming ||
                       status.state == scan::SequencerState::kArming ||
                       status.state == scan::SequencerState::kSweeping ||
                       status.state == scan::SequencerState::kFinishing;
  if (!running) throw HttpError(409, "no scan is running");
  control_.Abort(reason);
  SendJson(res, 200, {{"aborted", status.scan_id}});
}

void ApiServer::HandleGetScan(const Request& req, Response& res) {
  SendJson(res, 200, Summary(store_.Get(ScanIdFrom(req))));
}

void ApiServer::HandleDeleteScan(const Request& req, Response& res) {
  const std::string id = ScanIdFrom(req);
  store_.Delete(id);
  {
    std::lock_guard lock(sha_mutex_);
    sha_cache_.erase(id);
  }
  SendJson(res, 200, {{"deleted", id}});
}

void ApiServer::HandleArchive(const Request& req, Response& res) {
  const std::string id = ScanIdFrom(req);
  const std::string follow = req.get_param_value("follow");
  if (follow == "1") {
    FollowArchive(req, res, id);
    return;
  }
  if (!follow.empty() && follow != "0") throw HttpError(400, "follow: expected 0 or 1");
  if (req.has_param("offset")) throw HttpError(400, "offset: only with follow=1 (else use Range)");
  ServeArchiveFile(req, res, id);
}

std::string ApiServer::ArchiveSha256(const std::string& id, const fs::path& path) {
  const uintmax_t size = fs::file_size(path);
  const fs::file_time_type mtime = fs::last_write_time(path);
  {
    std::lock_guard lock(sha_mutex_);
    const auto it = sha_cache_.find(id);
    if (it != sha_cache_.end() && it->second.size == size && it->second.mtime == mtime) {
      return it->second.sha256;
    }
  }
  // Hashed outside the lock: two first downloads may both hash; both get the same answer.
  const std::string sha = protocol::Sha256::HexOfFile(path);
  std::lock_guard lock(sha_mutex_);
  sha_cache_[id] = ShaEntry{size, mtime, sha};
  return sha;
}

void ApiServer::ServeArchiveFile(const Request& req, Response& res, const std::string& id) {
  const store::ScanInfo info = store_.Get(id);
  if (info.state == store::ScanState::kWriting) {
    throw HttpError(409, "scan " + id + " is being written; add ?follow=1 to stream it live");
  }
  const fs::path path = store_.Path(id);
  auto file = std::make_shared<FileDescriptor>(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (file->fd < 0) throw HttpError(404, "scan " + id + " has no archive");
  const std::string sha = ArchiveSha256(id, path);
  const uint64_t size = fs::file_size(path);

  res.set_header("Accept-Ranges", "bytes");
  res.set_header("ETag", "\"" + sha + "\"");
  res.set_header(std::string(protocol::kSha256Header).c_str(), sha);
  res.set_header("Content-Disposition", "attachment; filename=\"" + id + ".mscan\"");
  SetVersionHeader(res);
  ByteRange range{0, size - 1};
  if (req.has_header("Range")) {
    const auto parsed = ParseRange(req.get_header_value("Range"), size);
    if (!parsed) {
      res.set_header("Content-Range", "bytes */" + std::to_string(size));
      SendError(res, 416,
                "Range: expected one satisfiable range (bytes=N-, bytes=N-M or bytes=-S) of a " +
                    std::to_string(size) + "-byte archive");
      return;
    }
    range = *parsed;
    res.status = 206;
    res.set_header("Content-Range", "bytes " + std::to_string(range.first) + "-" +
                                        std::to_string(range.last) + "/" + std::to_string(size));
  } else {
    res.status = 200;
  }
  const uint64_t start = range.first;
  res.set_content_provider(range.last - range.first + 1, "application/octet-stream",
                           [file, start](size_t offset, size_t length, httplib::DataSink& sink) {
                             std::vector<char> buffer(std::min(length, kReadChunk));
                             const ssize_t n =
                                 ReadAt(file->fd, buffer.data(), buffer.size(), start + offset);
                             if (n <= 0)
                               return false;  // the file shrank or failed: cut the response
                             return sink.write(buffer.data(), static_cast<size_t>(n));
                           });
}

bool ApiServer::AcquireStream(Response& res) {
  if (++streams_ > options_.max_streams) {
    --streams_;
    SendError(res, 503, "too many live streams; try again later");
    return false;
  }
  return true;
}

void ApiServer::FollowArchive(const Request& req, Response& res, const std::string& id) {
  if (req.has_header("Range")) throw HttpError(400, "Range: use ?offset=N with follow=1");
  uint64_t offset = 0;
  if (req.has_param("offset")) {
    const auto parsed = ParseUnsigned(req.get_param_value("offset"));
    if (!parsed) throw HttpError(400, "offset: expected a byte offset (digits)");
    offset = *parsed;
  }
  store_.Get(id);  // kInvalidId / kNotFound before anything else
  // The archive is renamed from .partial when the scan finishes; an open descriptor
  // follows the rename, so only the open itself may race it.
  int fd = -1;
  for (int attempt = 0; attempt < 2 && fd < 0; ++attempt) {
    fd = ::open(store_.Path(id).c_str(), O_RDONLY | O_CLOEXEC);
  }
  auto file = std::make_shared<FileDescriptor>(fd);
  if (file->fd < 0) throw HttpError(404, "scan " + id + " has no archive");
  if (store_.Get(id).state != store::ScanState::kWriting) {
    const uint64_t size = fs::file_size(store_.Path(id));
    if (offset > size) {
      throw HttpError(416, "offset " + std::to_string(offset) + " is past the end of the " +
                               std::to_string(size) + "-byte archive");
    }
  }
  if (!AcquireStream(res)) return;
  res.status = 200;
  res.set_header("Cache-Control", "no-store");
  SetVersionHeader(res);
  struct Follow {
    uint64_t position;
    std::vector<char> buffer = std::vector<char>(kReadChunk);
  };
  auto follow = std::make_shared<Follow>(Follow{offset});
  res.set_chunked_content_provider(
      "application/octet-stream",
      [this, file, follow, id](size_t, httplib::DataSink& sink) {
        if (stopping_) return false;
        auto read = [&] {
          return ReadAt(file->fd, follow->buffer.data(), follow->buffer.size(), follow->position);
        };
        ssize_t n = read();
        if (n == 0) {
          // At the end of what is written: done once the scan has finished (then every
          // byte, up to the footer, is in the file), else wait for more.
          bool writing = false;
          try {
            writing = store_.Get(id).state == store::ScanState::kWriting;
          } catch (const store::StoreError&) {
            return false;  // deleted under us
          }
          if (writing) {
            std::this_thread::sleep_for(options_.follow_poll);
            return true;
          }
          n = read();
          if (n == 0) {
            sink.done();
            return true;
          }
        }
        if (n < 0) return false;
        follow->position += static_cast<uint64_t>(n);
        return sink.write(follow->buffer.data(), static_cast<size_t>(n));
      },
      [this](bool) { --streams_; });
}

void ApiServer::HandleEvents(const Request&, Response& res) {
  if (!AcquireStream(res)) return;
  struct Queue {
    std::mutex mutex;
    std::condition_variable ready;
    std::deque<scan::ScanEvent> events;
    std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
  };
  auto queue = std::make_shared<Queue>();
  // The client first hears where the sequencer is now, then every change.
  queue->events.push_back(scan::ScanEvent{scan::ScanEvent::Type::kState, control_.Status()});
  const int handle = control_.Subscribe([queue](const scan::ScanEvent& event) {
    {
      std::lock_guard lock(queue->mutex);
      if (queue->events.size() >= kMaxQueuedEvents) queue->events.pop_front();
      queue->events.push_back(event);
    }
    queue->ready.notify_one();
  });
  res.status = 200;
  res.set_header("Cache-Control", "no-store");
  SetVersionHeader(res);
  res.set_chunked_content_provider(
      "text/event-stream",
      [this, queue](size_t, httplib::DataSink& sink) {
        std::string out;
        {
          std::unique_lock lock(queue->mutex);
          queue->ready.wait_for(lock, std::chrono::milliseconds(200),
                                [&] { return !queue->events.empty() || stopping_; });
          if (stopping_) return false;
          while (!queue->events.empty()) {
            out += FormatEvent(queue->events.front());
            queue->events.pop_front();
          }
        }
        const auto now = std::chrono::steady_clock::now();
        if (out.empty()) {
          if (now - queue->last_write < options_.keepalive_interval) return true;
          out = ": keepalive\n\n";  // finds a vanished client, keeps proxies from timing out
        }
        queue->last_write = now;
        return sink.write(out.data(), out.size());
      },
      [this, handle](bool) {
        control_.Unsubscribe(handle);
        --streams_;
      });
}

void ApiServer::HandleGetCalibration(const Request&, Response& res) {
  const auto text = calibration_.Get();
  if (!text) throw HttpError(404, "no calibration stored on this device");
  res.status = 200;
  res.set_header(std::string(protocol::kCalibrationSha256Header).c_str(), calibration_.Sha256());
  SetVersionHeader(res);
  res.set_content(*text, "application/json");
}

void ApiServer::HandlePutCalibration(const Request& req, Response& res) {
  if (req.body.empty()) throw HttpError(400, "request body: expected calibration.json");
  const std::string sha = calibration_.Put(req.body, "calibration");
  SendJson(res, 200, {{"sha256", sha}});
}

void ApiServer::HandleCapture(const Request& req, Response& res) {
  const json body = ParseBodyObject(req, false);
  const JsonReader r(body, "request body");
  r.AllowOnly({"camera", "lasers_on"});
  const std::string camera = r.String("camera");
  const bool lasers_on = r.Bool("lasers_on", false);
  bool known = false;
  for (const board::BoardCamera& c : board_.cameras) known = known || c.name == camera;
  if (!known)
    throw HttpError(400, "request body: camera: no camera \"" + camera + "\" on this board");
  const scan::CapturedFrame frame = control_.Capture(camera, lasers_on);
  if (frame.width <= 0 || frame.height <= 0 ||
      frame.pixels.size() != static_cast<size_t>(frame.width) * static_cast<size_t>(frame.height)) {
    throw HttpError(500, "the camera returned a malformed frame");
  }
  // Binary PGM: every image tool (and OpenCV) reads it, and it carries the size.
  std::string pgm =
      "P5\n" + std::to_string(frame.width) + " " + std::to_string(frame.height) + "\n255\n";
  pgm.append(reinterpret_cast<const char*>(frame.pixels.data()), frame.pixels.size());
  res.status = 200;
  res.set_header("X-Mirrorscan-Camera", frame.camera);
  res.set_header("X-Mirrorscan-Lasers-On", frame.lasers_on ? "1" : "0");
  res.set_header("X-Mirrorscan-Timestamp-Ns", std::to_string(frame.timestamp_ns));
  SetVersionHeader(res);
  res.set_content(pgm, "image/x-portable-graymap");
}

void ApiServer::HandlePreview(const Request& req, Response& res) {
  const std::string camera = req.get_param_value("camera");
  const std::string lasers = req.get_param_value("lasers");
  if (lasers != "" && lasers != "0" && lasers != "1")
    throw HttpError(400, "lasers: expected 0 or 1");
  bool known = false;
  for (const board::BoardCamera& c : board_.cameras) known = known || c.name == camera;
  if (!known) throw HttpError(400, "camera: no camera \"" + camera + "\" on this board");
  const bool lasers_on = lasers == "1";
  PreviewEntry entry;
  {
    // Nothing is captured unless someone asks; several viewers share one capture.
    std::lock_guard lock(preview_mutex_);
    PreviewEntry& cached = preview_cache_[camera + (lasers_on ? "+lasers" : "")];
    const auto now = std::chrono::steady_clock::now();
    if (cached.png.empty() || now - cached.time >= options_.preview_interval) {
      const scan::CapturedFrame frame = control_.Capture(camera, lasers_on);
      if (frame.width <= 0 || frame.height <= 0 ||
          frame.pixels.size() !=
              static_cast<size_t>(frame.width) * static_cast<size_t>(frame.height)) {
        throw HttpError(500, "the camera returned a malformed frame");
      }
      const ImageView view{frame.pixels.data(), frame.width, frame.height, frame.width};
      const std::vector<Peak> peaks = ExtractPeaks(view, board_.peaks);
      cached.png =
          RenderPreviewPng(frame.pixels, frame.width, frame.height, peaks, options_.preview_scale);
      cached.peaks = peaks.size();
      cached.time = std::chrono::steady_clock::now();
    }
    entry = cached;
  }
  res.status = 200;
  res.set_header("Cache-Control", "no-store");
  res.set_header("X-Mirrorscan-Peaks", std::to_string(entry.peaks));
  SetVersionHeader(res);
  res.set_content(entry.png, "image/png");
}

}  // namespace mirrorscan::service

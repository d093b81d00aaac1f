#include "host/client/device_client.h"

#include <fstream>
#include <optional>
#include <thread>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"

namespace mirrorscan::client {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kApi(protocol::kApiPrefix);

std::pair<std::string, int> SplitHostPort(const std::string& host_port) {
  const size_t colon = host_port.rfind(':');
  const bool bracketed = host_port.find(']') != std::string::npos;
  if (colon == std::string::npos || (bracketed && colon < host_port.find(']'))) {
    if (host_port.empty()) throw DeviceError(0, "usage", "--host: expected host:port");
    return {host_port, 8080};
  }
  const std::string port = host_port.substr(colon + 1);
  if (colon == 0 || port.empty() || port.size() > 5 ||
      port.find_first_not_of("0123456789") != std::string::npos || std::stoi(port) < 1 ||
      std::stoi(port) > 65535) {
    throw DeviceError(0, "usage",
                      "--host " + host_port + ": expected host:port with port 1..65535");
  }
  std::string host = host_port.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  return {host, std::stoi(port)};
}

// The device's JSON error as a DeviceError, or the status line when the body is not one.
[[noreturn]] void ThrowHttp(int status, const std::string& body, const std::string& what) {
  const json j = json::parse(body, nullptr, false);
  if (j.is_object() && j.contains("error")) {
    const auto error = j.get<protocol::ApiError>();
    throw DeviceError(status, error.error,
                      what + ": " + error.message + " (HTTP " + std::to_string(status) + ")");
  }
  throw DeviceError(status, std::string(protocol::ErrorCode(status)),
                    what + ": HTTP " + std::to_string(status));
}

bool IsTransient(httplib::Error error) {
  return error == httplib::Error::Read || error == httplib::Error::Connection ||
         error == httplib::Error::Write || error == httplib::Error::ConnectionTimeout;
}

uint64_t FileSize(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : size;
}

fs::path PartialPath(const fs::path& out) { return out.string() + ".partial"; }

}  // namespace

struct DeviceClient::Http {
  Http(const std::string& host, int port) : client(host, port) {}
  httplib::Client client;
};

DeviceClient::DeviceClient(const std::string& host_port, std::string token,
                           DeviceClientOptions options)
    : host_port_(host_port), token_(std::move(token)), options_(options) {
  const auto [host, port] = SplitHostPort(host_port);
  http_ = std::make_unique<Http>(host, port);
  http_->client.set_connection_timeout(options_.connect_timeout);
  http_->client.set_read_timeout(options_.read_timeout);
  http_->client.set_write_timeout(options_.read_timeout);
  if (!token_.empty()) http_->client.set_default_headers({{"Authorization", "Bearer " + token_}});
}

DeviceClient::~DeviceClient() = default;

namespace {

// Sends one request and returns the body of a 2xx answer; anything else throws.
template <typename Call>
std::string Expect2xx(const std::string& host_port, const std::string& what, Call call) {
  httplib::Result res = call();
  if (!res) {
    throw DeviceError(0, "connection",
                      what + ": cannot reach the device at " + host_port + " (" +
                          httplib::to_string(res.error()) + ")");
  }
  if (res->status < 200 || res->status >= 300) ThrowHttp(res->status, res->body, what);
  return res->body;
}

json ParseJson(const std::string& body, const std::string& what) {
  json j = json::parse(body, nullptr, false);
  if (j.is_discarded()) throw DeviceError(0, "protocol", what + ": the device sent malformed JSON");
  return j;
}

}  // namespace

protocol::DeviceStatus DeviceClient::Status() {
  const std::string body =
      Expect2xx(host_port_, "status", [&] { return http_->client.Get(kApi + "/status"); });
  try {
    return ParseJson(body, "status").get<protocol::DeviceStatus>();
  } catch (const json::exception& e) {
    throw DeviceError(0, "protocol", std::string("status: unexpected answer: ") + e.what());
  }
}

std::vector<protocol::ScanSummary> DeviceClient::List() {
  const std::string body =
      Expect2xx(host_port_, "list", [&] { return http_->client.Get(kApi + "/scans"); });
  try {
    return ParseJson(body, "list").at("scans").get<std::vector<protocol::ScanSummary>>();
  } catch (const json::exception& e) {
    throw DeviceError(0, "protocol", std::string("list: unexpected answer: ") + e.what());
  }
}

protocol::ScanSummary DeviceClient::Get(const std::string& id) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  const std::string body =
      Expect2xx(host_port_, "scan " + id, [&] { return http_->client.Get(kApi + "/scans/" + id); });
  try {
    return ParseJson(body, "scan").get<protocol::ScanSummary>();
  } catch (const json::exception& e) {
    throw DeviceError(0, "protocol", std::string("scan: unexpected answer: ") + e.what());
  }
}

std::string DeviceClient::StartScan() {
  const std::string body = Expect2xx(host_port_, "start scan", [&] {
    return http_->client.Post(kApi + "/scans", "", "application/json");
  });
  const json j = ParseJson(body, "start scan");
  if (!j.contains("id") || !j["id"].is_string()) {
    throw DeviceError(0, "protocol", "start scan: the device sent no scan id");
  }
  return j["id"].get<std::string>();
}

std::string DeviceClient::AbortScan(const std::string& reason) {
  const json request = reason.empty() ? json::object() : json{{"reason", reason}};
  const std::string body = Expect2xx(host_port_, "abort scan", [&] {
    return http_->client.Post(kApi + "/scans/current/abort", request.dump(), "application/json");
  });
  const json j = ParseJson(body, "abort scan");
  if (!j.contains("aborted") || !j["aborted"].is_string()) {
    throw DeviceError(0, "protocol", "abort scan: the device did not name the scan");
  }
  return j["aborted"].get<std::string>();
}

void DeviceClient::Delete(const std::string& id) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  Expect2xx(host_port_, "delete " + id,
            [&] { return http_->client.Delete(kApi + "/scans/" + id); });
}

std::string DeviceClient::ArchiveSha256(const std::string& id) {
  // One byte is enough to read the headers of a finished archive.
  std::string sha;
  Expect2xx(host_port_, "checksum of " + id, [&] {
    auto res = http_->client.Get(kApi + "/scans/" + id + "/archive", {{"Range", "bytes=0-0"}});
    if (res) sha = res->get_header_value(std::string(protocol::kSha256Header).c_str());
    return res;
  });
  if (sha.size() != 64) throw DeviceError(0, "protocol", "the device sent no SHA-256 for " + id);
  return sha;
}

FetchResult DeviceClient::Fetch(const std::string& id, const fs::path& out,
                                const ProgressCallback& progress) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  const fs::path partial = PartialPath(out);
  TransferProgress state;
  std::string expected_sha;
  for (int attempt = 0;; ++attempt) {
    const uint64_t have = FileSize(partial);
    httplib::Headers headers;
    if (have > 0) headers.emplace("Range", "bytes=" + std::to_string(have) + "-");
    std::ofstream file;
    int status = 0;
    std::string error_body;
    httplib::Result res = http_->client.Get(
        kApi + "/scans/" + id + "/archive", headers,
        [&](const httplib::Response& response) {
          status = response.status;
          if (status != 200 && status != 206) return true;  // the body is the error
          const std::string sha =
              response.get_header_value(std::string(protocol::kSha256Header).c_str());
          if (!expected_sha.empty() && sha != expected_sha) {
            // The archive changed under us: start over.
            fs::remove(partial);
            status = -1;
            return false;
          }
          expected_sha = sha;
          const bool append = status == 206;
          file.open(partial, std::ios::binary | (append ? std::ios::app : std::ios::trunc));
          state.bytes = append ? have : 0;
          const std::string range = response.get_header_value("Content-Range");
          const size_t slash = range.rfind('/');
          state.total = slash != std::string::npos
                            ? std::stoull(range.substr(slash + 1))
                            : std::stoull("0" + response.get_header_value("Content-Length"));
          return static_cast<bool>(file);
        },
        [&](const char* data, size_t length) {
          if (status != 200 && status != 206) {
            if (error_body.size() < 65536) error_body.append(data, length);
            return true;
          }
          file.write(data, static_cast<std::streamsize>(length));
          state.bytes += length;
          if (progress) progress(state);
          return static_cast<bool>(file);
        });
    file.close();
    if (status == -1 && attempt < options_.max_retries) continue;
    if (status == 416 && have > 0 && attempt == 0) {
      fs::remove(partial);  // a stale partial file longer than the archive
      continue;
    }
    if (res && (status == 200 || status == 206)) break;
    if (res) ThrowHttp(status, error_body, "fetch " + id);
    if (!IsTransient(res.error()) || attempt >= options_.max_retries) {
      throw DeviceError(0, "connection",
                        "fetch " + id + ": connection to " + host_port_ + " failed (" +
                            httplib::to_string(res.error()) + ") after " + std::to_string(attempt) +
                            " retries; run the same command again to resume");
    }
    ++state.reconnects;
    std::this_thread::sleep_for(options_.retry_delay);
  }
  const std::string sha = protocol::Sha256::HexOfFile(partial);
  if (sha != expected_sha) {
    fs::remove(partial);
    throw DeviceError(0, "checksum",
                      "fetch " + id + ": SHA-256 mismatch (device " + expected_sha + ", received " +
                          sha + "); the download was discarded");
  }
  fs::rename(partial, out);
  return FetchResult{out, FileSize(out), sha, state.reconnects};
}

FetchResult DeviceClient::Follow(const std::string& id, const fs::path& out,
                                 const ProgressCallback& progress) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  const fs::path partial = PartialPath(out);
  TransferProgress state;
  // Counts frames for the progress display; fed from the start so a resumed stream lines up.
  ScanStreamReader reader;
  auto feed = [&](const char* data, size_t length) {
    reader.Feed(std::span(reinterpret_cast<const uint8_t*>(data), length));
    while (auto record = reader.Next()) {
      if (record->type == static_cast<uint32_t>(RecordType::kFrame)) ++state.frames;
    }
  };
  if (FileSize(partial) > 0) {
    std::ifstream in(partial, std::ios::binary);
    std::vector<char> buffer(1 << 16);
    while (in.read(buffer.data(), static_cast<std::streamsize>(buffer.size())) || in.gcount() > 0) {
      feed(buffer.data(), static_cast<size_t>(in.gcount()));
    }
  }
  for (int attempt = 0;; ++attempt) {
    state.bytes = FileSize(partial);
    std::ofstream file(partial, std::ios::binary | std::ios::app);
    if (!file) throw DeviceError(0, "io", "cannot write " + partial.string());
    int status = 0;
    std::string error_body;
    httplib::Result res = http_->client.Get(
        kApi + "/scans/" + id + "/archive?follow=1&offset=" + std::to_string(state.bytes),
        [&](const httplib::Response& response) {
          status = response.status;
          return true;
        },
        [&](const char* data, size_t length) {
          if (status != 200) {
            if (error_body.size() < 65536) error_body.append(data, length);
            return true;
          }
          file.write(data, static_cast<std::streamsize>(length));
          file.flush();  // the partial file is what a reconnect resumes from
          state.bytes += length;
          feed(data, length);
          if (progress) progress(state);
          return static_cast<bool>(file);
        });
    file.close();
    if (res && status == 200) break;
    if (res) ThrowHttp(status, error_body, "follow " + id);
    if (!IsTransient(res.error()) || attempt >= options_.max_retries) {
      throw DeviceError(0, "connection",
                        "follow " + id + ": connection to " + host_port_ + " failed (" +
                            httplib::to_string(res.error()) +
                            "); run the same command again to resume");
    }
    ++state.reconnects;
    std::this_thread::sleep_for(options_.retry_delay);
  }
  const std::string expected_sha = ArchiveSha256(id);
  const std::string sha = protocol::Sha256::HexOfFile(partial);
  if (sha != expected_sha) {
    fs::remove(partial);
    throw DeviceError(0, "checksum",
                      "follow " + id + ": SHA-256 mismatch (device " + expected_sha +
                          ", received " + sha + "); the stream was discarded");
  }
  fs::rename(partial, out);
  return FetchResult{out, FileSize(out), sha, state.reconnects};
}

std::string DeviceClient::GetCalibration() {
  return Expect2xx(host_port_, "calibration get",
                   [&] { return http_->client.Get(kApi + "/calibration"); });
}

std::string DeviceClient::PutCalibration(const std::string& text) {
  const std::string body = Expect2xx(host_port_, "calibration put", [&] {
    return http_->client.Put(kApi + "/calibration", text, "application/json");
  });
  return ParseJson(body, "calibration put").value("sha256", "");
}

std::string DeviceClient::Capture(const std::string& camera, bool lasers_on) {
  const std::string request = json{{"camera", camera}, {"lasers_on", lasers_on}}.dump();
  return Expect2xx(host_port_, "capture", [&] {
    return http_->client.Post(kApi + "/captures", request, "application/json");
  });
}

void DeviceClient::PutResult(const std::string& id, const std::string& name, const fs::path& file) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  if (protocol::FindResultKind(name) == nullptr) {
    throw DeviceError(0, "usage", "not a result name: " + name);
  }
  std::error_code ec;
  const uint64_t size = fs::file_size(file, ec);
  if (ec) throw DeviceError(0, "io", "cannot read " + file.string());
  auto in = std::make_shared<std::ifstream>(file, std::ios::binary);
  if (!*in) throw DeviceError(0, "io", "cannot read " + file.string());
  const std::string what = "upload " + name + " of " + id;
  Expect2xx(host_port_, what, [&] {
    // Streamed from the file with its length: the device checks the size before reading.
    return http_->client.Put(
        kApi + "/scans/" + id + "/results/" + name, static_cast<size_t>(size),
        [in](size_t offset, size_t length, httplib::DataSink& sink) {
          std::vector<char> buffer(std::min<size_t>(length, 1 << 16));
          in->seekg(static_cast<std::streamoff>(offset));
          in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
          const std::streamsize n = in->gcount();
          if (n <= 0) return false;
          return sink.write(buffer.data(), static_cast<size_t>(n));
        },
        "application/octet-stream");
  });
}

std::vector<protocol::ResultInfo> DeviceClient::Results(const std::string& id) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  const std::string body = Expect2xx(host_port_, "results of " + id, [&] {
    return http_->client.Get(kApi + "/scans/" + id + "/results");
  });
  try {
    return ParseJson(body, "results").at("results").get<std::vector<protocol::ResultInfo>>();
  } catch (const json::exception& e) {
    throw DeviceError(0, "protocol", std::string("results: unexpected answer: ") + e.what());
  }
}

std::string DeviceClient::GetResult(const std::string& id, const std::string& name) {
  if (!protocol::IsValidScanId(id)) throw DeviceError(0, "usage", "not a scan id: " + id);
  if (protocol::FindResultKind(name) == nullptr) {
    throw DeviceError(0, "usage", "not a result name: " + name);
  }
  return Expect2xx(host_port_, name + " of " + id,
                   [&] { return http_->client.Get(kApi + "/scans/" + id + "/results/" + name); });
}

void DeviceClient::Events(const std::function<bool(const protocol::ScanEventMessage&)>& on_event) {
  std::string pending;
  int status = 0;
  std::string error_body;
  bool stopped = false;
  httplib::Result res = http_->client.Get(
      kApi + "/events",
      [&](const httplib::Response& response) {
        status = response.status;
        return true;
      },
      [&](const char* data, size_t length) {
        if (status != 200) {
          error_body.append(data, length);
          return true;
        }
        pending.append(data, length);
        // Events end with a blank line; "data:" lines carry the JSON.
        for (size_t end; (end = pending.find("\n\n")) != std::string::npos;) {
          const std::string event = pending.substr(0, end);
          pending.erase(0, end + 2);
          const size_t data_at = event.find("data: ");
          if (data_at == std::string::npos) continue;
          const size_t line_end = event.find('\n', data_at);
          const json j =
              json::parse(event.substr(data_at + 6, line_end - data_at - 6), nullptr, false);
          if (j.is_discarded()) continue;
          try {
            if (!on_event(j.get<protocol::ScanEventMessage>())) {
              stopped = true;
              return false;
            }
          } catch (const json::exception&) {
            continue;
          }
        }
        return true;
      });
  if (stopped) return;
  if (res && status != 200) ThrowHttp(status, error_body, "events");
  throw DeviceError(0, "connection",
                    "events: the stream from " + host_port_ + " ended (" +
                        (res ? std::string("closed") : httplib::to_string(res.error())) + ")");
}

}  // namespace mirrorscan::client

#include "host/cli/device_command.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/protocol/protocol.h"
#include "host/cli/device_discovery.h"
#include "host/cli/exit_status.h"
#include "host/cli/pose_command.h"
#include "host/cli/process_command.h"
#include "host/client/device_client.h"

namespace mirrorscan::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct DeviceOptions {
  std::string host = "127.0.0.1:8080";
  std::string token;
  bool json = false;
  std::string id;
  std::string out;
  bool wait = false;
  std::string reason;  // abort
  bool follow = false;
  std::string camera;
  bool lasers_on = false;
  std::string calibration_file;
  double discover_seconds = 2.0;
  // watch
  bool process = false;
  std::string board;
  int count = 0;  // scans to handle before exiting; 0: until stopped
};

client::DeviceClient Connect(const DeviceOptions& o) {
  return client::DeviceClient(o.host, o.token);
}

void PrintJson(const json& j) { std::cout << j.dump(2) << "\n"; }

std::string Megabytes(uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f MB", static_cast<double>(bytes) / 1e6);
  return text;
}

// A one-line progress bar on stderr, redrawn at most ten times a second, only on a terminal
// (logs and pipes get the final line only).
class ProgressBar {
 public:
  explicit ProgressBar(std::string label) : label_(std::move(label)), tty_(::isatty(2) == 1) {}
  ~ProgressBar() { Finish(); }

  void Update(double fraction, const std::string& detail) {
    last_detail_ = detail;
    if (!tty_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_draw_ < std::chrono::milliseconds(100) && fraction < 1.0) return;
    last_draw_ = now;
    constexpr int kWidth = 30;
    std::string bar;
    if (fraction >= 0) {
      const int filled = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * kWidth);
      bar = "[" + std::string(filled, '#') + std::string(kWidth - filled, '.') + "] " +
            std::to_string(static_cast<int>(std::clamp(fraction, 0.0, 1.0) * 100)) + "% ";
    }
    std::fprintf(stderr, "\r\033[K%s %s%s", label_.c_str(), bar.c_str(), detail.c_str());
    drawn_ = true;
  }

  void Finish() {
    if (finished_) return;
    finished_ = true;
    if (drawn_) {
      std::fprintf(stderr, "\n");
    } else if (!last_detail_.empty()) {
      std::fprintf(stderr, "%s %s\n", label_.c_str(), last_detail_.c_str());
    }
  }

 private:
  std::string label_;
  bool tty_;
  bool drawn_ = false;
  bool finished_ = false;
  std::string last_detail_;
  std::chrono::steady_clock::time_point last_draw_{};
};

client::ProgressCallback DownloadProgress(ProgressBar& bar) {
  return [&bar](const client::TransferProgress& p) {
    std::string detail = Megabytes(p.bytes);
    if (p.total > 0) detail += " of " + Megabytes(p.total);
    if (p.frames > 0) detail += ", " + std::to_string(p.frames) + " frames";
    if (p.reconnects > 0) detail += ", resumed " + std::to_string(p.reconnects) + "x";
    bar.Update(p.total > 0 ? static_cast<double>(p.bytes) / static_cast<double>(p.total) : -1,
               detail);
  };
}

fs::path OutPath(const DeviceOptions& o, const std::string& id) {
  return o.out.empty() ? fs::path(id + ".mscan") : fs::path(o.out);
}

json FetchJson(const std::string& id, const client::FetchResult& r) {
  return {{"id", id},
          {"path", r.path.string()},
          {"bytes", r.bytes},
          {"sha256", r.sha256},
          {"reconnects", r.reconnects}};
}

void Status(const DeviceOptions& o) {
  const protocol::DeviceStatus s = Connect(o).Status();
  if (o.json) return PrintJson(s);
  std::printf("device     %s (board %s, firmware %s)\n", o.host.c_str(), s.board.c_str(),
              s.firmware_version.c_str());
  std::printf("state      %s", s.scan.state.c_str());
  if (!s.scan.scan_id.empty()) {
    std::printf(" (scan %s, %.0f%%, %llu frames)", s.scan.scan_id.c_str(), s.scan.progress * 100,
                static_cast<unsigned long long>(s.scan.frames));
  }
  if (!s.scan.reason.empty()) std::printf(": %s", s.scan.reason.c_str());
  std::printf("\ncalibration %s\n", s.calibration_sha256.empty()
                                        ? "none stored"
                                        : s.calibration_sha256.substr(0, 16).c_str());
  if (!s.calibration_problem.empty())
    std::printf("           the stored one was set aside: %s\n", s.calibration_problem.c_str());
  std::printf("disk       %s free of %s; scans use %s\n", Megabytes(s.disk.free_bytes).c_str(),
              Megabytes(s.disk.total_bytes).c_str(), Megabytes(s.disk.scans_bytes).c_str());
}

void List(const DeviceOptions& o) {
  const auto scans = Connect(o).List();
  if (o.json) return PrintJson(scans);
  if (scans.empty()) {
    std::printf("no scans on the device\n");
    return;
  }
  std::printf("%-22s %-9s %-21s %7s %9s %10s\n", "ID", "STATE", "CREATED", "FRAMES", "PEAKS",
              "SIZE");
  for (const auto& s : scans) {
    std::printf("%-22s %-9s %-21s %7llu %9llu %10s\n", s.id.c_str(), s.state.c_str(),
                s.created.c_str(), static_cast<unsigned long long>(s.frames),
                static_cast<unsigned long long>(s.peaks), Megabytes(s.bytes).c_str());
  }
}

bool IsEndState(const std::string& state) {
  return state == "done" || state == "fault" || state == "aborted";
}

// Follows the scan's progress (server-sent events; status polling when the stream drops
// or is refused, e.g. all stream slots taken) until it ends; returns the end state.
protocol::ScanProgress WaitForScan(client::DeviceClient& device, const std::string& id) {
  ProgressBar bar("scan " + id);
  protocol::ScanProgress last;
  auto on_progress = [&](const protocol::ScanProgress& p) {
    if (p.scan_id != id) return true;  // the state before our scan took over
    last = p;
    bar.Update(p.progress, p.state + ", " + std::to_string(p.frames) + " frames");
    return !IsEndState(p.state);
  };
  try {
    device.Events([&](const protocol::ScanEventMessage& e) { return on_progress(e.scan); });
  } catch (const client::DeviceError& e) {
    if (e.status() != 0 && e.status() != 503) throw;
    // The event stream dropped or was refused: poll until the scan ends.
    while (on_progress(device.Status().scan)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }
  bar.Finish();
  return last;
}

void Scan(const DeviceOptions& o) {
  client::DeviceClient device = Connect(o);
  const std::string id = device.StartScan();
  json result = {{"id", id}};
  if (o.follow) {
    ProgressBar bar("follow " + id);
    const client::FetchResult r = device.Follow(id, OutPath(o, id), DownloadProgress(bar));
    bar.Finish();
    result.update(FetchJson(id, r));
    result["state"] = device.Get(id).state;
  } else if (o.wait) {
    const protocol::ScanProgress end = WaitForScan(device, id);
    result["state"] = end.state;
    result["frames"] = end.frames;
    if (end.state != "done") {
      throw std::runtime_error("scan " + id + " ended " + end.state +
                               (end.reason.empty() ? "" : ": " + end.reason));
    }
  }
  if (o.json) return PrintJson(result);
  std::printf("%s\n", id.c_str());
  if (result.contains("path")) {
    std::fprintf(stderr, "scan %s %s; archive %s (%s, sha256 %s)\n", id.c_str(),
                 result.value("state", "").c_str(), result["path"].get<std::string>().c_str(),
                 Megabytes(result["bytes"]).c_str(), result["sha256"].get<std::string>().c_str());
  }
}

void Fetch(const DeviceOptions& o) {
  client::DeviceClient device = Connect(o);
  ProgressBar bar("fetch " + o.id);
  client::FetchResult r;
  try {
    r = o.follow ? device.Follow(o.id, OutPath(o, o.id), DownloadProgress(bar))
                 : device.Fetch(o.id, OutPath(o, o.id), DownloadProgress(bar));
  } catch (const client::DeviceError& e) {
    if (e.status() != 409 || o.follow) throw;
    throw std::runtime_error(std::string(e.what()) + "; it is still running: add --follow");
  }
  bar.Finish();
  if (o.json) return PrintJson(FetchJson(o.id, r));
  std::printf("%s\n", r.path.string().c_str());
  std::fprintf(stderr, "%s: %s, sha256 %s verified%s\n", r.path.string().c_str(),
               Megabytes(r.bytes).c_str(), r.sha256.c_str(),
               r.reconnects > 0 ? (", resumed " + std::to_string(r.reconnects) + "x").c_str() : "");
}

void Abort(const DeviceOptions& o) {
  const std::string id = Connect(o).AbortScan(o.reason);
  if (o.json) return PrintJson({{"aborted", id}});
  std::printf("aborted %s\n", id.c_str());
}

void Delete(const DeviceOptions& o) {
  Connect(o).Delete(o.id);
  if (o.json) return PrintJson({{"deleted", o.id}});
  std::printf("deleted %s\n", o.id.c_str());
}

void CalibrationGet(const DeviceOptions& o) {
  const std::string text = Connect(o).GetCalibration();
  if (o.out.empty()) {
    std::cout << text;
    if (!text.empty() && text.back() != '\n') std::cout << "\n";
    return;
  }
  std::ofstream(o.out, std::ios::binary) << text;
  if (o.json) return PrintJson({{"path", o.out}});
  std::printf("%s\n", o.out.c_str());
}

void CalibrationPut(const DeviceOptions& o) {
  std::ifstream in(o.calibration_file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + o.calibration_file);
  std::ostringstream text;
  text << in.rdbuf();
  const std::string sha = Connect(o).PutCalibration(text.str());
  if (o.json) return PrintJson({{"sha256", sha}});
  std::printf("stored; sha256 %s\n", sha.c_str());
}

void Capture(const DeviceOptions& o) {
  const std::string pgm = Connect(o).Capture(o.camera, o.lasers_on);
  const std::string out =
      o.out.empty() ? o.camera + (o.lasers_on ? "-lasers" : "-dark") + ".pgm" : o.out;
  std::ofstream file(out, std::ios::binary);
  file.write(pgm.data(), static_cast<std::streamsize>(pgm.size()));
  if (!file) throw std::runtime_error("cannot write " + out);
  if (o.json) return PrintJson({{"path", out}, {"camera", o.camera}, {"lasers_on", o.lasers_on}});
  std::printf("%s\n", out.c_str());
}

// The scan processed here, in this process (pipeline::Process, as `mirrorscan process
// ARCHIVE --calibration C --out DIR --upload HOST` does): its exit status, 0 when the results
// are on the device. A job that fails is reported and the watch goes on.
int ProcessScan(const DeviceOptions& o, const fs::path& archive, const fs::path& out,
                json* report) {
  pipeline::ProcessOptions options;
  options.upload = o.host;
  options.token = o.token;
  int status = 0;
  try {
    RunProcess(archive, o.calibration_file, o.board, out, options);
  } catch (const CommandExit& e) {
    (*report)["process_error"] = e.what();
    status = e.status();
  } catch (const std::exception& e) {
    (*report)["process_error"] = e.what();
    status = kExitFailure;
  }
  // The pose check's verdict from summary.json: a run that fails after it has one too.
  std::ifstream in(out / "summary.json");
  const json summary = json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (summary.is_object() && summary.contains("pose")) (*report)["pose"] = summary["pose"];
  return status;
}

// One finished scan: fetched (retried while the device still finishes it), then processed
// and uploaded when asked. Returns the line (or JSON) that reports it.
json HandleFinishedScan(const DeviceOptions& o, client::DeviceClient& device,
                        const std::string& id) {
  const fs::path archive = fs::path(o.out) / (id + ".mscan");
  json report = {{"id", id}};
  client::FetchResult fetched;
  for (int attempt = 0;; ++attempt) {
    try {
      fetched = device.Fetch(id, archive);
      break;
    } catch (const client::DeviceError& e) {
      // 409: the archive is still being closed; a connection error: the device restarts.
      if ((e.status() != 409 && e.status() != 0) || attempt >= 20) throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }
  report.update(FetchJson(id, fetched));
  if (o.process) {
    const fs::path out = fs::path(o.out) / id;
    report["process_exit"] = ProcessScan(o, archive, out, &report);
    report["results"] = out.string();
  }
  return report;
}

void Watch(const DeviceOptions& o) {
  if (o.process && o.calibration_file.empty()) {
    throw CommandExit(kExitUsage, "watch --process needs --calibration C.json");
  }
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (!fs::is_directory(o.out, ec)) {
    throw CommandExit(kExitUsage, "--out " + o.out + ": cannot create the directory");
  }
  client::DeviceClientOptions client_options;
  client_options.read_timeout = std::chrono::seconds(30);  // keep-alives come every 5 s
  client::DeviceClient device(o.host, o.token, client_options);
  std::set<std::string> handled;
  int done = 0;
  bool stop = false;
  std::fprintf(stderr, "watch: following %s; finished scans go to %s\n", o.host.c_str(),
               o.out.c_str());
  auto on_event = [&](const protocol::ScanEventMessage& e) {
    const protocol::ScanProgress& p = e.scan;
    if (p.scan_id.empty() || handled.count(p.scan_id) > 0 || !IsEndState(p.state)) return true;
    handled.insert(p.scan_id);
    // A scan that ended before the watch began and was fetched here already is not redone.
    if (p.state == "done" && e.type == "state" && done == 0 &&
        fs::exists(fs::path(o.out) / (p.scan_id + ".mscan"))) {
      return true;
    }
    json report;
    if (p.state != "done") {
      report = {{"id", p.scan_id}, {"state", p.state}, {"reason", p.reason}};
      std::fprintf(stderr, "watch: scan %s ended %s%s; not fetched\n", p.scan_id.c_str(),
                   p.state.c_str(), p.reason.empty() ? "" : (": " + p.reason).c_str());
    } else {
      report = HandleFinishedScan(o, device, p.scan_id);
      report["state"] = "done";
      std::fprintf(stderr, "watch: scan %s fetched (%s)%s\n", p.scan_id.c_str(),
                   Megabytes(report["bytes"]).c_str(),
                   !o.process ? ""
                   : report["process_exit"] == 0
                       ? ", processed and uploaded"
                       : (", process exit " + report["process_exit"].dump() + ": " +
                          report.value("process_error", std::string()))
                             .c_str());
    }
    // The pose check's advice at once, for the shop assistant beside the cabinet.
    if (report.contains("pose")) {
      for (const std::string& line : PoseLines(report["pose"])) {
        std::fprintf(stderr, "watch: scan %s pose: %s\n", p.scan_id.c_str(), line.c_str());
      }
    }
    if (o.json) {
      std::cout << report.dump() << std::endl;
    } else if (report.contains("path")) {
      std::cout << report["path"].get<std::string>() << std::endl;
    }
    ++done;
    stop = o.count > 0 && done >= o.count;
    return !stop;
  };
  for (int failures = 0; !stop;) {
    try {
      device.Events(on_event);
    } catch (const client::DeviceError& e) {
      // A dropped stream (the device restarted, the network blinked): follow again; a
      // refusal (401/403, 404) ends the watch.
      if (e.status() != 0 && e.status() != 503 && e.status() != 429) throw;
      if (++failures % 10 == 1) std::fprintf(stderr, "watch: %s; retrying\n", e.what());
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  }
}

void Discover(const DeviceOptions& o) {
  const std::vector<DiscoveredDevice> devices = DiscoverDevices(o.discover_seconds);
  if (o.json) {
    json list = json::array();
    for (const auto& d : devices) {
      list.push_back({{"name", d.name},
                      {"host", d.host},
                      {"address", d.address},
                      {"port", d.port},
                      {"txt", d.txt}});
    }
    return PrintJson(list);
  }
  if (devices.empty()) {
    std::printf("no mirrorscan devices found on the LAN\n");
    return;
  }
  for (const auto& d : devices) {
    std::printf("%-24s --host %s:%d  (%s)\n", d.name.c_str(), d.address.c_str(), d.port,
                d.host.c_str());
  }
}

}  // namespace

void AddDeviceCommands(CLI::App& app) {
  auto options = std::make_shared<DeviceOptions>();
  CLI::App* device = app.add_subcommand(
      "device", "Talk to a scanner over the network: status, start and fetch scans, calibration");
  device->require_subcommand(1);
  device->footer(
      "\nExamples (the virtual board, mirrorscand on 127.0.0.1:8080):\n"
      "  export MIRRORSCAN_TOKEN=virtual-dev-token-not-a-secret\n"
      "  mirrorscan device scan --wait           start a scan, show its progress\n"
      "  mirrorscan device list\n"
      "  mirrorscan device fetch ID              download to ID.mscan, verified\n"
      "  mirrorscan device scan --follow         stream the archive while it is scanned\n"
      "Options may also follow the subcommand. More: docs/cli-device.md");
  // --host/--token/--json may come before or after the subcommand.
  device->fallthrough();
  device->add_option("--host", options->host, "the device as host:port")
      ->envname("MIRRORSCAN_HOST")
      ->capture_default_str();
  device
      ->add_option("--token", options->token,
                   "bearer token for starting, deleting, uploading (or set MIRRORSCAN_TOKEN)")
      ->envname(std::string(protocol::kTokenEnvironmentVariable));
  device->add_flag("--json", options->json, "print machine-readable JSON on stdout");

  device->add_subcommand("status", "Show the device's state, scan progress, calibration and disk")
      ->callback([options] { Status(*options); });
  device->add_subcommand("list", "List the scans stored on the device, newest first")
      ->callback([options] { List(*options); });

  auto* scan = device->add_subcommand(
      "scan",
      "Start a scan (needs the token); prints its id. --wait or --follow to see it through");
  scan->add_flag("--wait", options->wait, "wait until the scan ends, showing its progress");
  scan->add_flag("--follow", options->follow,
                 "stream the archive live while the scan runs, into ID.mscan (or --out)");
  scan->add_option("--out", options->out, "where --follow writes the archive");
  scan->callback([options] { Scan(*options); });

  auto* fetch = device->add_subcommand(
      "fetch", "Download a scan's archive to ID.mscan (or --out), resuming and verifying SHA-256");
  fetch->add_option("id", options->id, "scan id, as `device list` shows it")->required();
  fetch->add_option("--out", options->out, "output file (default: ID.mscan here)");
  fetch->add_flag("--follow", options->follow, "stream a scan that is still running, live");
  fetch->callback([options] { Fetch(*options); });

  auto* abort = device->add_subcommand(
      "abort",
      "Abort the running scan: lasers off, slide stopped, archive kept as \"aborted\" "
      "(needs the token)");
  abort->add_option("--reason", options->reason, "recorded in the archive's footer");
  abort->callback([options] { Abort(*options); });

  auto* remove =
      device->add_subcommand("delete", "Delete a scan from the device (needs the token)");
  remove->add_option("id", options->id, "scan id")->required();
  remove->callback([options] { Delete(*options); });

  auto* calibration =
      device->add_subcommand("calibration", "Read or replace the device's calibration.json");
  calibration->require_subcommand(1);
  auto* get = calibration->add_subcommand("get", "Print the stored calibration (or write --out)");
  get->add_option("--out", options->out, "write it to this file instead of stdout");
  get->callback([options] { CalibrationGet(*options); });
  auto* put = calibration->add_subcommand(
      "put", "Upload a calibration.json; the device validates it before storing (needs the token)");
  put->add_option("file", options->calibration_file, "calibration.json to upload")
      ->required()
      ->check(CLI::ExistingFile);
  put->callback([options] { CalibrationPut(*options); });

  auto* capture = device->add_subcommand(
      "capture",
      "Capture one raw frame (8-bit PGM) for calibration, lasers on or off (needs the token)");
  capture->add_option("--camera", options->camera, "camera name from the board (e.g. upper)")
      ->required();
  capture->add_flag("--lasers", options->lasers_on, "switch the lasers on for this frame");
  capture->add_option("--out", options->out,
                      "output file (default: CAMERA-lasers.pgm or CAMERA-dark.pgm)");
  capture->callback([options] { Capture(*options); });

  auto* discover = device->add_subcommand(
      "discover", "List scanners announcing _mirrorscan._tcp on the LAN (needs avahi-daemon)");
  discover->add_option("--timeout", options->discover_seconds, "seconds to listen")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  discover->callback([options] { Discover(*options); });

  auto* watch = device->add_subcommand(
      "watch",
      "Follow the device's events; fetch each scan that finishes into --out, and with "
      "--process reconstruct, mesh, measure and upload the results to the device");
  watch->add_option("--out", options->out, "folder for the archives (and results)")->required();
  watch->add_flag("--process", options->process,
                  "process each fetched scan into OUT/ID/ and upload its results (as `mirrorscan "
                  "process ... --upload`, in this process)");
  watch->add_option("--calibration", options->calibration_file, "calibration.json for --process")
      ->check(CLI::ExistingFile);
  watch
      ->add_option("--board", options->board,
                   "board.json for --process (bounding cylinder, the pose check's reach)")
      ->check(CLI::ExistingFile);
  watch->add_option("--count", options->count, "exit after this many scans ended (0: never)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  watch->callback([options] { Watch(*options); });
}

}  // namespace mirrorscan::cli

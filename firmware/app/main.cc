// mirrorscand: the scanner's daemon (docs/firmware.md). Builds the board's devices, opens
// the scan store, runs the sequencer and its safety supervisor until SIGTERM/SIGINT.
//
// Exit codes: 0 stopped by a signal, or --exit-after-scan and the scan completed, or every
// --check passed; 1 --exit-after-scan and the scan ended in fault or aborted, or a --check
// failed; 2 bad command line or
// board.json; 3 a device or the device API failed to start; 4 the data
// directory cannot be used; 5 an internal error (the lasers were switched off first).

#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/config/json_reader.h"
#include "firmware/app/self_check.h"
#include "firmware/board/board_config.h"
#include "firmware/board/devices.h"
#include "firmware/board/virtual/linked_simulator.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"
#include "firmware/scan/sequencer.h"
#include "firmware/service/api_server.h"
#include "firmware/service/calibration_store.h"
#include "firmware/service/token.h"
#include "firmware/store/scan_store.h"

namespace {

using namespace mirrorscan;  // NOLINT: a main file

enum ExitCode { kOk = 0, kScanFailed = 1, kUsage = 2, kHardware = 3, kStore = 4, kInternal = 5 };

constexpr const char* kUsageText = R"(usage: mirrorscand --board BOARD.json --data-dir DIR [options]

  --board FILE        the board description (boards/*/board.json)
  --data-dir DIR      the scan store (created if missing)
  --listen HOST:PORT  the device API's address (default: board.json service.listen;
                      port 0 takes any free port, which the log names)
  --scene FILE        virtual boards only: the scene to render instead of virtual.scene
  --interlock-state FILE
                      virtual boards only: mirror the laser interlock's state (the
                      monostable's last trigger) into FILE for outside observers
  --line-state FILE   virtual boards only: mirror the output lines' levels (lasers,
                      LED) into FILE for outside observers (docs/firmware.md)
  --fault-on-sigusr2 FAULT
                      virtual boards only: SIGUSR2 injects FAULT, one of drive-fault
                      (the simulated drive latches fault code 0x42) and
                      camera-stall:NAME (that camera stops delivering frames)
  --web-dir DIR       the web page's files (default: ../share/mirrorscan/web beside
                      this program, as installed and as built; none there: no page)
  --check             check the board once and exit (0 all passed, 1 a check failed):
                      cameras stream, lasers toggle (seen by a camera), drive answers and
                      homes, disk room and writes, calibration stored and valid, clock;
                      one line per check. The daemon must not be running.
  --check-fault lasers-stuck|drive-silent
                      virtual boards only, for tests: the laser lines never go off, or
                      the simulated drive stops answering
  --watchdog-hang-hook
                      test hook: SIGUSR2 hangs the control loop for good (an event
                      listener that never returns), so the systemd watchdog's pings stop
  --scan-on-start     start one scan as soon as the daemon is ready (origin "test")
  --exit-after-scan   exit once a scan has ended (0 complete, 1 fault or aborted)
  --log-level LEVEL   trace, debug, info (default), warn, error
  --version, --help

Signals: SIGTERM/SIGINT abort a running scan (lasers off at once) and stop the daemon;
SIGUSR1 presses the virtual button (boards with gpio.backend "virtual"); SIGUSR2
injects the --fault-on-sigusr2 fault (or, with --watchdog-hang-hook, hangs the loop).
)";

struct Args {
  std::filesystem::path board;
  std::filesystem::path data_dir;
  std::string listen;
  std::filesystem::path scene;
  std::filesystem::path web_dir;
  std::optional<std::filesystem::path> interlock_state;
  std::optional<std::filesystem::path> line_state;
  std::string sigusr2_fault;
  bool scan_on_start = false;
  bool exit_after_scan = false;
  bool check = false;
  std::string check_fault;
  bool watchdog_hang_hook = false;
  std::string log_level = "info";
};

// Throws std::invalid_argument with one line for the user.
std::optional<Args> ParseArgs(int argc, char** argv) {
  Args args;
  const std::vector<std::string> all(argv + 1, argv + argc);
  for (size_t i = 0; i < all.size(); ++i) {
    const std::string& flag = all[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= all.size()) throw std::invalid_argument(flag + " needs a value");
      return all[++i];
    };
    if (flag == "--help" || flag == "-h") {
      std::fputs(kUsageText, stdout);
      return std::nullopt;
    } else if (flag == "--version") {
      std::printf("mirrorscand %s\n", MIRRORSCAN_VERSION);
      return std::nullopt;
    } else if (flag == "--board") {
      args.board = value();
    } else if (flag == "--data-dir") {
      args.data_dir = value();
    } else if (flag == "--listen") {
      args.listen = value();
    } else if (flag == "--scene") {
      args.scene = value();
    } else if (flag == "--web-dir") {
      args.web_dir = value();
    } else if (flag == "--interlock-state") {
      args.interlock_state = value();
    } else if (flag == "--line-state") {
      args.line_state = value();
    } else if (flag == "--fault-on-sigusr2") {
      args.sigusr2_fault = value();
      if (args.sigusr2_fault != "drive-fault" &&
          args.sigusr2_fault.rfind("camera-stall:", 0) != 0) {
        throw std::invalid_argument("--fault-on-sigusr2: drive-fault or camera-stall:NAME, not " +
                                    args.sigusr2_fault);
      }
    } else if (flag == "--check") {
      args.check = true;
    } else if (flag == "--check-fault") {
      args.check_fault = value();
      if (args.check_fault != "lasers-stuck" && args.check_fault != "drive-silent") {
        throw std::invalid_argument("--check-fault: expected lasers-stuck or drive-silent");
      }
    } else if (flag == "--watchdog-hang-hook") {
      args.watchdog_hang_hook = true;
    } else if (flag == "--scan-on-start") {
      args.scan_on_start = true;
    } else if (flag == "--exit-after-scan") {
      args.exit_after_scan = true;
    } else if (flag == "--log-level") {
      args.log_level = value();
    } else {
      throw std::invalid_argument("unknown option " + flag + " (see --help)");
    }
  }
  if (args.board.empty()) throw std::invalid_argument("--board is required");
  if (args.data_dir.empty()) throw std::invalid_argument("--data-dir is required");
  if (spdlog::level::from_str(args.log_level) == spdlog::level::off && args.log_level != "off") {
    throw std::invalid_argument("--log-level: unknown level " + args.log_level);
  }
  return args;
}

// systemd's notification protocol: one datagram per message to $NOTIFY_SOCKET.
class SystemdNotifier {
 public:
  SystemdNotifier() {
    const char* path = std::getenv("NOTIFY_SOCKET");
    if (path == nullptr || path[0] == '\0') return;
    address_.sun_family = AF_UNIX;
    std::strncpy(address_.sun_path, path, sizeof(address_.sun_path) - 1);
    length_ = offsetof(sockaddr_un, sun_path) + std::strlen(path);
    if (path[0] == '@') address_.sun_path[0] = '\0';  // abstract namespace
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (const char* usec = std::getenv("WATCHDOG_USEC")) {
      watchdog_interval_ = std::chrono::microseconds(std::atoll(usec)) / 2;
    }
  }
  ~SystemdNotifier() {
    if (fd_ >= 0) close(fd_);
  }
  void Send(const std::string& message) {
    if (fd_ < 0) return;
    if (sendto(fd_, message.data(), message.size(), MSG_NOSIGNAL,
               reinterpret_cast<const sockaddr*>(&address_), length_) < 0) {
      spdlog::warn("sd_notify {}: {}", message, std::strerror(errno));
    }
  }
  // Pings the watchdog at half its interval while `alive`.
  void Tick(bool alive) {
    if (fd_ < 0 || watchdog_interval_.count() <= 0 || !alive) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ping_ >= watchdog_interval_) {
      Send("WATCHDOG=1");
      last_ping_ = now;
    }
  }

 private:
  int fd_ = -1;
  sockaddr_un address_{};
  socklen_t length_ = 0;
  std::chrono::microseconds watchdog_interval_{0};
  std::chrono::steady_clock::time_point last_ping_{};
};

// For std::terminate: the lasers go off before the process dies.
hal::LaserBank* g_lasers = nullptr;

void TerminateSafely() {
  if (g_lasers != nullptr) g_lasers->SafeOff();
  std::fputs("mirrorscand: terminate called; lasers switched off\n", stderr);
  std::abort();
}

// A press as the virtual line sees it: active for twice the debounce time, then released.
void PressVirtualButton(board::BoardDevices& devices, int debounce_ms) {
  if (devices.virtual_button == nullptr) {
    spdlog::warn("SIGUSR1: this board has no virtual button; ignored");
    return;
  }
  const bool low = devices.button_active_low;
  devices.virtual_button->InjectEdge(hal::SteadyNowNs(), !low);
  std::this_thread::sleep_for(std::chrono::milliseconds(2 * debounce_ms + 10));
  devices.virtual_button->InjectEdge(hal::SteadyNowNs(), low);
}

// A fault on the virtual board's simulated hardware, for the fault tests of the process
// (--fault-on-sigusr2). Empty when the fault cannot be injected on this board: then the
// problem is in `problem`.
std::function<void()> VirtualFault(const std::string& fault, const board::BoardConfig& config,
                                   board::BoardDevices& devices, std::string& problem) {
  if (fault == "drive-fault") {
    board::SimulatedDrive* sim = devices.drive_sim.get();
    if (sim == nullptr) {
      problem = "drive-fault needs drive.backend \"virtual\"";
      return {};
    }
    return [sim] { sim->InjectFault(0x42); };
  }
  const std::string name = fault.substr(fault.find(':') + 1);
  for (size_t i = 0; i < config.cameras.size(); ++i) {
    if (config.cameras[i].name != name) continue;
    auto* camera = dynamic_cast<hal::ThreadedCamera*>(devices.cameras[i].get());
    if (camera == nullptr) {
      problem = "camera " + name + " is not simulated (replay or virtual)";
      return {};
    }
    return [camera] { camera->SetStalled(true); };
  }
  problem = "no camera named " + name;
  return {};
}

// --web-dir, or the page installed (and built) beside the program: bin/../share/mirrorscan/web.
std::filesystem::path WebDir(const Args& args) {
  std::error_code ec;
  if (!args.web_dir.empty()) {
    if (!std::filesystem::is_regular_file(args.web_dir / "index.html", ec)) {
      throw ConfigError("--web-dir " + args.web_dir.string() + ": no index.html there");
    }
    return args.web_dir;
  }
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path beside = self.parent_path().parent_path() / "share/mirrorscan/web";
  if (!ec && std::filesystem::is_regular_file(beside / "index.html", ec)) return beside;
  spdlog::info("no web page ({} has none; --web-dir DIR)", beside.string());
  return {};
}

bool Ended(scan::SequencerState state) {
  return state == scan::SequencerState::kDone || state == scan::SequencerState::kFault ||
         state == scan::SequencerState::kAborted;
}

// --check: one line per check on stdout, exit 0 when every one passed.
int Check(const Args& args, const board::BoardConfig& config) {
  if (!args.check_fault.empty() && config.gpio.backend != hal::GpioBackend::kVirtual) {
    spdlog::error("--check-fault is for virtual boards only");
    return kUsage;
  }
  app::SelfCheckOptions options;
  options.board_file = args.board;
  options.data_dir = args.data_dir;
  options.scene = args.scene;
  options.simulator = board::LinkedSimulator();
  options.fault_lasers_stuck = args.check_fault == "lasers-stuck";
  options.fault_drive_silent = args.check_fault == "drive-silent";
  const std::vector<app::CheckResult> results =
      app::RunSelfCheck(config, options, [](const app::CheckResult& r) {
        std::printf("%-4s %s: %s\n", r.ok ? "ok" : "FAIL", r.name.c_str(), r.detail.c_str());
        std::fflush(stdout);
      });
  const auto failed = std::count_if(results.begin(), results.end(),
                                    [](const app::CheckResult& r) { return !r.ok; });
  std::printf("%s: %zu checks, %ld failed\n", failed == 0 ? "check passed" : "check FAILED",
              results.size(), static_cast<long>(failed));
  return failed == 0 ? kOk : kScanFailed;
}

int Run(const Args& args, const sigset_t& signals) {
  board::BoardConfig config;
  try {
    config = board::BoardConfig::Load(args.board);
  } catch (const ConfigError& e) {
    spdlog::error("{}", e.what());
    return kUsage;
  }
  if (args.check) return Check(args, config);
  const std::string listen = args.listen.empty() ? config.service.listen : args.listen;

  std::unique_ptr<store::ScanStore> store;
  try {
    store::ScanStoreOptions store_options;
    store_options.keep_finished = static_cast<size_t>(config.store.retention_scans);
    store = store::ScanStore::Open(args.data_dir, store_options);
  } catch (const std::exception& e) {
    spdlog::error("data dir {}: {}", args.data_dir.string(), e.what());
    return kStore;
  }

  board::BoardDevices devices;
  try {
    board::DeviceOptions device_options;
    device_options.simulator = board::LinkedSimulator();
    device_options.scene = args.scene;
    device_options.interlock_state_file = args.interlock_state;
    device_options.line_state_file = args.line_state;
    devices = board::MakeBoardDevices(config, device_options);
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", args.board.string(), e.what());
    return kHardware;
  }
  if (args.line_state && config.gpio.backend != hal::GpioBackend::kVirtual) {
    spdlog::error("--line-state is for boards with gpio.backend \"virtual\"");
    return kUsage;
  }
  std::function<void()> inject_fault;
  if (!args.sigusr2_fault.empty()) {
    std::string problem;
    inject_fault = VirtualFault(args.sigusr2_fault, config, devices, problem);
    if (!inject_fault) {
      spdlog::error("--fault-on-sigusr2 {}: {}", args.sigusr2_fault, problem);
      return kUsage;
    }
  }
  g_lasers = devices.gpio.lasers.get();
  struct ForgetLasers {  // before the devices go, whichever way Run returns
    ~ForgetLasers() { g_lasers = nullptr; }
  } forget_lasers;

  scan::SequencerDevices sequencer_devices;
  for (size_t i = 0; i < config.cameras.size(); ++i) {
    sequencer_devices.cameras.push_back({config.cameras[i].name, devices.cameras[i].get()});
  }
  sequencer_devices.lasers = devices.gpio.lasers.get();
  sequencer_devices.interlock = devices.gpio.interlock.get();
  if (sequencer_devices.interlock == nullptr) {
    spdlog::warn(
        "{}: no gpio.interlock: nothing outside this process turns the lasers off "
        "if it freezes (docs/boards.md)",
        args.board.string());
  }
  sequencer_devices.led = devices.gpio.led.get();
  sequencer_devices.button = devices.gpio.button.get();
  sequencer_devices.drive = devices.drive.get();

  scan::SequencerOptions options;
  options.board = config.board;
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  options.device = host;
  options.firmware_version = MIRRORSCAN_VERSION;
  options.data_dir = args.data_dir;
  options.sweep_start_mm = config.scan.sweep_start_mm;
  options.sweep_end_mm = config.scan.sweep_end_mm;
  options.speed_mm_s = config.scan.speed_mm_s;
  options.home_timeout_s = config.scan.home_timeout_s;
  options.peaks = config.peaks;
  options.supervisor.max_laser_on_s = config.scan.max_laser_on_s;
  options.supervisor.camera_stall =
      std::chrono::microseconds(static_cast<int64_t>(config.scan.camera_stall_ms * 1000));

  std::unique_ptr<scan::Sequencer> sequencer;
  try {
    sequencer = std::make_unique<scan::Sequencer>(sequencer_devices, *store, options);
  } catch (const std::exception& e) {
    spdlog::error("sequencer: {}", e.what());
    return kHardware;
  }

  // The device API; stopped before the sequencer goes (it holds references to it).
  std::unique_ptr<service::CalibrationStore> calibration;
  std::unique_ptr<service::ApiServer> api;
  try {
    calibration = std::make_unique<service::CalibrationStore>(args.data_dir / "calibration.json");
    if (const std::string problem = calibration->problem(); !problem.empty()) {
      spdlog::error("calibration: {}; the device runs uncalibrated until one is uploaded", problem);
    }
    service::ApiServerOptions api_options;
    api_options.firmware_version = MIRRORSCAN_VERSION;
    api_options.web_dir = WebDir(args);
    api = std::make_unique<service::ApiServer>(*store, *sequencer, config, *calibration,
                                               service::ResolveServiceToken(config.service),
                                               api_options);
    const int port = api->Start(listen);
    spdlog::info("mirrorscand {} ready: board {}, data dir {}, device API on {}:{}",
                 MIRRORSCAN_VERSION, config.board, args.data_dir.string(),
                 listen.substr(0, listen.rfind(':')), port);
  } catch (const ConfigError& e) {
    spdlog::error("{}", e.what());
    return kUsage;
  } catch (const std::exception& e) {
    spdlog::error("device API: {}", e.what());
    return kHardware;
  }

  // The watchdog's test hook: once armed (SIGUSR2), the next event the sequencer emits
  // from its control loop never returns, as a driver call that hangs would not.
  std::atomic<bool> hang{false};
  if (args.watchdog_hang_hook) {
    sequencer->Subscribe([&hang](const scan::ScanEvent&) {
      while (hang.load()) std::this_thread::sleep_for(std::chrono::seconds(1));
    });
  }

  SystemdNotifier notifier;
  notifier.Send("READY=1");
  bool scan_started = false;
  if (args.scan_on_start) {
    try {
      sequencer->StartScan("test");
      scan_started = true;
    } catch (const std::exception& e) {
      spdlog::error("--scan-on-start: {}", e.what());
      if (args.exit_after_scan) return kScanFailed;
    }
  }

  int exit_code = kOk;
  while (true) {
    // Only while the control loop and the supervisor are running (a blocked drive call
    // may hold the loop for up to ~1 s; the watchdog allows WatchdogSec).
    notifier.Tick(sequencer->Alive(2'000'000'000));
    const timespec timeout{0, 50 * 1000 * 1000};
    const int signal = sigtimedwait(&signals, nullptr, &timeout);
    if (signal == SIGTERM || signal == SIGINT) {
      spdlog::info("{}: stopping", signal == SIGTERM ? "SIGTERM" : "SIGINT");
      notifier.Send("STOPPING=1");
      sequencer->Abort(signal == SIGTERM ? "SIGTERM" : "SIGINT");
      break;
    }
    if (signal == SIGUSR2 && args.watchdog_hang_hook) {
      spdlog::warn("SIGUSR2: --watchdog-hang-hook: hanging the control loop");
      hang = true;
    }
    if (signal == SIGUSR1) {
      PressVirtualButton(devices, config.gpio.debounce_ms);
      scan_started = true;
    }
    if (signal == SIGUSR2 && !args.watchdog_hang_hook) {
      if (inject_fault) {
        spdlog::warn("SIGUSR2: injecting {}", args.sigusr2_fault);
        inject_fault();
      } else {
        spdlog::warn("SIGUSR2: no --fault-on-sigusr2; ignored");
      }
    }
    const scan::ScanStatus status = sequencer->Status();
    if (args.exit_after_scan && scan_started && !status.scan_id.empty() && Ended(status.state)) {
      exit_code = status.state == scan::SequencerState::kDone ? kOk : kScanFailed;
      break;
    }
  }
  api.reset();
  // The sequencer finishes a running scan as aborted and leaves the outputs safe.
  sequencer.reset();
  if (!devices.gpio.lasers->SafeOff()) {
    spdlog::critical("a laser line could not be driven off");
    return kInternal;
  }
  spdlog::info("mirrorscand stopped; lasers off");
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  // Signals are taken synchronously by the main thread; every thread started later
  // inherits the mask, so no handler ever runs on a worker.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGUSR1);
  sigaddset(&signals, SIGUSR2);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::set_terminate(TerminateSafely);

  std::optional<Args> args;
  try {
    args = ParseArgs(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mirrorscand: %s\n", e.what());
    return kUsage;
  }
  if (!args) return kOk;
  spdlog::set_level(spdlog::level::from_str(args->log_level));
  try {
    return Run(*args, signals);
  } catch (const std::exception& e) {
    // Run's devices are gone (their destructors switched the lasers off).
    spdlog::critical("internal error: {}", e.what());
    return kInternal;
  }
}

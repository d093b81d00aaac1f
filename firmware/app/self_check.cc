#include "firmware/app/self_check.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <deque>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"
#include "common/peaks/peaks.h"
#include "common/protocol/protocol.h"
#include "firmware/board/devices.h"
#include "firmware/service/calibration_store.h"

namespace mirrorscan::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string Seconds(Clock::duration d) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f s", std::chrono::duration<double>(d).count());
  return text;
}

// Frames from a camera: `count` of them after skipping `skip`, within `timeout`. Copies the
// pixels so the buffers go straight back to the camera.
struct Grabbed {
  std::vector<std::vector<uint8_t>> frames;
  int width = 0, height = 0;
  uint64_t dropped = 0;
  Clock::duration first_frame{};
  std::string error;
};

Grabbed Grab(hal::Camera& camera, int skip, int count, std::chrono::milliseconds timeout,
             const std::function<void()>& while_waiting = nullptr) {
  Grabbed out;
  std::mutex mutex;
  std::condition_variable ready;
  int seen = 0;
  std::string end_error;
  const auto start = Clock::now();
  try {
    camera.Start(
        [&](hal::Frame frame) {
          std::lock_guard lock(mutex);
          if (seen == 0) out.first_frame = Clock::now() - start;
          if (seen++ >= skip && static_cast<int>(out.frames.size()) < count) {
            const ImageView view = frame.view();
            out.width = view.width;
            out.height = view.height;
            std::vector<uint8_t> pixels(static_cast<size_t>(view.width) * view.height);
            for (int y = 0; y < view.height; ++y) {
              std::memcpy(&pixels[static_cast<size_t>(y) * view.width], view.data + y * view.stride,
                          static_cast<size_t>(view.width));
            }
            out.frames.push_back(std::move(pixels));
          }
          ready.notify_all();
        },
        [&](const hal::HardwareError* error) {
          std::lock_guard lock(mutex);
          end_error = error != nullptr ? error->what() : "the stream ended";
          ready.notify_all();
        });
  } catch (const std::exception& e) {
    out.error = e.what();
    return out;
  }
  {
    std::unique_lock lock(mutex);
    const auto deadline = Clock::now() + timeout;
    while (static_cast<int>(out.frames.size()) < count && end_error.empty()) {
      if (while_waiting) {
        lock.unlock();
        while_waiting();
        lock.lock();
      }
      if (ready.wait_until(lock,
                           std::min(deadline, Clock::now() + std::chrono::milliseconds(20))) ==
              std::cv_status::timeout &&
          Clock::now() >= deadline) {
        break;
      }
    }
    if (static_cast<int>(out.frames.size()) < count && out.error.empty()) {
      out.error = !end_error.empty() ? end_error
                                     : std::to_string(out.frames.size()) + " of " +
                                           std::to_string(count) + " frames in " + Seconds(timeout);
    }
  }
  out.dropped = camera.dropped();
  camera.Stop();
  return out;
}

size_t PeakCount(const Grabbed& grabbed, const PeakParams& params) {
  size_t peaks = 0;
  for (const auto& pixels : grabbed.frames) {
    const ImageView view{pixels.data(), grabbed.width, grabbed.height, grabbed.width};
    peaks = std::max(peaks, ExtractPeaks(view, params).size());
  }
  return peaks;
}

// The lines the check drives when a stuck laser is simulated: on passes, off never does.
class StuckLasers final : public hal::LaserBank {
 public:
  explicit StuckLasers(hal::LaserBank& real) : real_(real) {}
  int count() const override { return real_.count(); }
  void Set(int laser, bool on) override {
    if (on) real_.Set(laser, on);
  }
  void SetAll(bool on) override {
    if (on) real_.SetAll(on);
  }
  std::vector<bool> states() const override { return real_.states(); }
  bool SafeOff() noexcept override { return true; }

 private:
  hal::LaserBank& real_;
};

CheckResult CheckDisk(const SelfCheckOptions& o) {
  CheckResult r{"disk", false, ""};
  std::error_code ec;
  if (!fs::is_directory(o.data_dir, ec)) {
    r.detail = "no data directory " + o.data_dir.string() + " (mirrorscand creates it at start)";
    return r;
  }
  const fs::space_info space = fs::space(o.data_dir, ec);
  if (ec) {
    r.detail = o.data_dir.string() + ": " + ec.message();
    return r;
  }
  // A write that reaches the disk, as a scan's first records must.
  const fs::path probe = o.data_dir / (".check-" + std::to_string(::getpid()));
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  std::string write_error;
  if (fd < 0) {
    write_error = std::strerror(errno);
  } else {
    const std::string block(1 << 20, '\0');
    if (::write(fd, block.data(), block.size()) != static_cast<ssize_t>(block.size()) ||
        ::fsync(fd) != 0) {
      write_error = errno != 0 ? std::strerror(errno) : "short write";
    }
    ::close(fd);
    ::unlink(probe.c_str());
  }
  const std::string free_text = std::to_string(space.available >> 20) + " MiB free of " +
                                std::to_string(space.capacity >> 20);
  if (!write_error.empty()) {
    r.detail = "cannot write 1 MiB in " + o.data_dir.string() + " (" + write_error + "); " +
               free_text + "; delete scans to make room";
  } else if (space.available < o.min_free_bytes) {
    r.detail = "disk full: " + free_text + ", a scan needs " +
               std::to_string(o.min_free_bytes >> 20) + " MiB; delete scans to make room";
  } else {
    r.ok = true;
    r.detail = free_text + " in " + o.data_dir.string() + ", writable";
  }
  return r;
}

CheckResult CheckCalibration(const SelfCheckOptions& o) {
  CheckResult r{"calibration", false, ""};
  const fs::path file = o.data_dir / "calibration.json";
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    r.detail = "none stored in " + file.string() +
               " (run the factory calibration, or: mirrorscan device calibration put FILE)";
    return r;
  }
  try {
    const nlohmann::json text = JsonReader::ParseFile(file);
    service::ValidateCalibration(text, file.string());
  } catch (const std::exception& e) {
    r.detail = std::string("invalid: ") + e.what();
    return r;
  }
  r.ok = true;
  r.detail = file.string() + " valid";
  return r;
}

CheckResult CheckClock(const SelfCheckOptions& o) {
  CheckResult r{"clock", false, ""};
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%dT%H%M%SZ", &tm);
  // The newest scan id: a clock behind it (no RTC, no NTP yet) would date new scans wrong.
  std::string newest;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(o.data_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() >= 21 && protocol::IsValidScanId(name.substr(0, 21))) {
      newest = std::max(newest, name.substr(0, 21));
    }
  }
  if (tm.tm_year + 1900 < 2025) {
    r.detail = std::string("the clock says ") + text +
               ": not set (no RTC, no NTP yet?); scan ids and dates would be wrong";
  } else if (!newest.empty() && std::string(stamp) < newest.substr(0, 16)) {
    r.detail = std::string("the clock says ") + text + ", before the newest scan " + newest +
               ": it went backwards";
  } else {
    r.ok = true;
    r.detail = text + std::string(newest.empty() ? "" : ", after the newest scan " + newest);
  }
  return r;
}

}  // namespace

std::vector<CheckResult> RunSelfCheck(const board::BoardConfig& config,
                                      const SelfCheckOptions& options,
                                      const std::function<void(const CheckResult&)>& report) {
  std::vector<CheckResult> results;
  auto add = [&](CheckResult r) {
    if (report) report(r);
    results.push_back(std::move(r));
  };

  board::BoardDevices devices;
  bool have_devices = false;
  try {
    board::DeviceOptions device_options;
    device_options.scene = options.scene;
    device_options.simulator = options.simulator;
    devices = board::MakeBoardDevices(config, device_options);
    have_devices = true;
  } catch (const std::exception& e) {
    add({"devices", false, std::string(e.what()) + " (cameras, lasers and drive not checked)"});
  }

  if (have_devices) {
    // The drive first: the lasers' check wants the slide at a known place.
    {
      CheckResult r{"drive", false, ""};
      if (options.fault_drive_silent && devices.drive_sim) devices.drive_sim->SetResponding(false);
      const auto start = Clock::now();
      try {
        devices.drive->Enable(true);
        devices.drive->Home(
            std::chrono::milliseconds(static_cast<int64_t>(config.scan.home_timeout_s * 1000)));
        const double position = devices.drive->Position();
        const hal::SlideStatus status = devices.drive->Status();
        r.ok = status.homed && !status.fault;
        char text[128];
        std::snprintf(text, sizeof(text), "answers, homed in %s, at %.1f mm (%s)",
                      Seconds(Clock::now() - start).c_str(), position,
                      hal::ToString(status).c_str());
        r.detail = text;
      } catch (const std::exception& e) {
        r.detail = std::string(e.what()) + " after " + Seconds(Clock::now() - start) +
                   " (wiring, power, Modbus address and baud rate: docs/slide-drive.md)";
      }
      add(r);
    }
    for (size_t i = 0; i < devices.cameras.size(); ++i) {
      CheckResult r{"camera " + config.cameras[i].name, false, ""};
      const auto start = Clock::now();
      const Grabbed grabbed = Grab(*devices.cameras[i], 1, 5, std::chrono::milliseconds(5000));
      if (!grabbed.error.empty()) {
        r.detail = "not streaming: " + grabbed.error;
      } else {
        r.ok = true;
        r.detail = "present, streaming: 6 frames " + std::to_string(grabbed.width) + "x" +
                   std::to_string(grabbed.height) + " in " + Seconds(Clock::now() - start) + ", " +
                   std::to_string(grabbed.dropped) + " dropped";
      }
      add(r);
    }
    // The lasers as the first camera sees them: peaks with the lines on, none with them off.
    if (!devices.cameras.empty()) {
      CheckResult r{"lasers", false, ""};
      hal::LaserBank& real = *devices.gpio.lasers;
      StuckLasers stuck(real);
      hal::LaserBank& lasers =
          options.fault_lasers_stuck ? static_cast<hal::LaserBank&>(stuck) : real;
      const auto kick = [&] {
        if (devices.gpio.interlock) devices.gpio.interlock->Kick();
      };
      try {
        lasers.SetAll(true);
        kick();
        const Grabbed on = Grab(*devices.cameras[0], 2, 2, std::chrono::milliseconds(5000), kick);
        lasers.SetAll(false);
        const Grabbed off = Grab(*devices.cameras[0], 2, 2, std::chrono::milliseconds(5000), kick);
        if (!on.error.empty() || !off.error.empty()) {
          r.detail = "no frames to see them: " + (on.error.empty() ? off.error : on.error);
        } else {
          const size_t peaks_on = PeakCount(on, config.peaks);
          const size_t peaks_off = PeakCount(off, config.peaks);
          const std::string counts = "camera " + config.cameras[0].name + " sees " +
                                     std::to_string(peaks_on) + " peaks with " +
                                     std::to_string(lasers.count()) + " lasers on, " +
                                     std::to_string(peaks_off) + " off";
          if (peaks_on < 50) {
            r.detail = counts + ": the lasers do not come on (power, MOSFETs, interlock)";
          } else if (peaks_off * 5 > peaks_on) {
            r.detail = counts + ": the lasers do not go off (a stuck MOSFET or line)";
          } else {
            r.ok = true;
            r.detail = counts + ": they toggle";
          }
        }
      } catch (const std::exception& e) {
        r.detail = e.what();
      }
      real.SafeOff();
      add(r);
    }
    try {
      devices.drive->Enable(false);
    } catch (const std::exception&) {
      // the drive check already said what is wrong
    }
  }
  add(CheckDisk(options));
  add(CheckCalibration(options));
  add(CheckClock(options));
  return results;
}

}  // namespace mirrorscan::app

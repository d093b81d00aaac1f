// The systemd watchdog (docs/firmware.md): mirrorscand pings WATCHDOG=1 on $NOTIFY_SOCKET
// while its control loop runs; when the loop hangs mid-sweep (the --watchdog-hang-hook
// test hook: an event listener that never returns) the pings stop, and the lasers are
// dark (the interlock is no longer triggered) before systemd would act on the missed
// ping. No systemd runs here: the test reads the socket. The units restart the daemon
// on a missed ping.
#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "firmware/hal/virtual/virtual_monostable.h"
#include "tests/support/loopback.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"
#include "tests/support/virtual_board.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using std::chrono::seconds;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

int64_t NowNs() { return Clock::now().time_since_epoch().count(); }

TEST(WatchdogTest, PingsStopWhenTheControlLoopHangsAndTheLasersAreDarkByThen) {
  const fs::path dir = test_support::FreshTempDir("mirrorscand_watchdog_test");
  // The virtual board with replay cameras (a stripe; no rendering) and a long sweep.
  const fs::path board_file = test_support::WriteVirtualBoard(dir, 1400, /*replay=*/true);
  const json board = json::parse(test_support::ReadFile(board_file));

  const fs::path socket_path = dir / "notify";
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::strncpy(address.sun_path, socket_path.c_str(), sizeof(address.sun_path) - 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
  timeval timeout{0, 50000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::mutex mutex;
  std::vector<std::pair<int64_t, std::string>> messages;
  std::atomic<bool> reading{true};
  std::thread reader([&] {
    while (reading) {
      char buffer[256];
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
      if (n <= 0) continue;
      std::lock_guard lock(mutex);
      messages.emplace_back(NowNs(), std::string(buffer, static_cast<size_t>(n)));
    }
  });
  const auto pings_since = [&](int64_t since_ns) {
    std::lock_guard lock(mutex);
    int count = 0;
    for (const auto& [t, m] : messages) count += (t >= since_ns && m == "WATCHDOG=1");
    return count;
  };
  const auto last_ping_ns = [&] {
    std::lock_guard lock(mutex);
    int64_t last = 0;
    for (const auto& [t, m] : messages) {
      if (m == "WATCHDOG=1") last = t;
    }
    return last;
  };

  const int port = test_support::FreeLoopbackPort();
  test_support::ChildOptions options;
  // WatchdogSec=1s as systemd would pass it: a ping every 0.5 s.
  options.env = {{"NOTIFY_SOCKET", socket_path.string()}, {"WATCHDOG_USEC", "1000000"}};
  test_support::ChildProcess daemon(
      MIRRORSCAND_PATH,
      {"--board", board_file.string(), "--data-dir", (dir / "data").string(), "--listen",
       "127.0.0.1:" + std::to_string(port), "--interlock-state", (dir / "interlock").string(),
       "--watchdog-hang-hook"},
      dir / "daemon.log", options);
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(5, 0);
  const std::string token = board["service"]["token"];
  const httplib::Headers auth = {{"Authorization", "Bearer " + token}};
  auto state = [&]() -> std::string {
    auto res = client.Get("/api/v1/status");
    if (!res || res->status != 200) return "";
    return json::parse(res->body)["scan"]["state"];
  };
  for (const auto end = Clock::now() + seconds(30); state().empty();) {
    ASSERT_LT(Clock::now(), end) << daemon.Log();
    std::this_thread::sleep_for(milliseconds(50));
  }
  auto started = client.Post("/api/v1/scans", auth, "", "application/json");
  ASSERT_TRUE(started && started->status == 201) << daemon.Log();
  for (const auto end = Clock::now() + seconds(30); state() != "sweeping";) {
    ASSERT_LT(Clock::now(), end) << daemon.Log();
    std::this_thread::sleep_for(milliseconds(20));
  }
  const int fd_state = ::open((dir / "interlock").c_str(), O_RDONLY);
  ASSERT_GE(fd_state, 0);
  const auto* interlock = static_cast<const hal::VirtualMonostable::SharedState*>(::mmap(
      nullptr, sizeof(hal::VirtualMonostable::SharedState), PROT_READ, MAP_SHARED, fd_state, 0));
  ::close(fd_state);
  ASSERT_NE(interlock, MAP_FAILED);
  const int64_t pulse_ns = interlock->pulse_ns;

  // Sweeping: the pings come, the interlock is kept triggered (the lasers lit).
  const int64_t sweep_ns = NowNs();
  std::this_thread::sleep_for(milliseconds(1100));
  EXPECT_GE(pings_since(sweep_ns), 2);
  EXPECT_LT(NowNs() - interlock->last_trigger_ns.load(), pulse_ns);

  daemon.Signal(SIGUSR2);  // the control loop hangs at its next progress event
  const int64_t hang_ns = NowNs();
  std::this_thread::sleep_for(seconds(5));
  const int64_t now_ns = NowNs();
  const int64_t last_ping = last_ping_ns();
  const int64_t last_trigger = interlock->last_trigger_ns.load();
  reading = false;
  reader.join();
  ::close(fd);
  // Pings stop: none in the last 2 s; the last one within the 2 s liveness window (plus
  // a ping interval and the event's own delay) of the hang.
  EXPECT_EQ(pings_since(now_ns - 2'000'000'000), 0);
  EXPECT_LT(last_ping - hang_ns, 3'000'000'000);
  // The lasers went dark a pulse after the loop's last trigger, before the last ping: by
  // the time systemd acts on the missed ping (a WatchdogSec after it) they are off.
  EXPECT_GE(now_ns - last_trigger, pulse_ns);
  EXPECT_LE(last_trigger + pulse_ns, last_ping + 500'000'000);
  std::printf(
      "watchdog: last ping %.2f s after SIGUSR2, "
      "lasers dark %.2f s after it (pulse %.0f ms)\n",
      (last_ping - hang_ns) / 1e9, (last_trigger + pulse_ns - hang_ns) / 1e9, pulse_ns / 1e6);
  ::munmap(const_cast<hal::VirtualMonostable::SharedState*>(interlock),
           sizeof(hal::VirtualMonostable::SharedState));
  daemon.Signal(SIGKILL);  // what systemd does after WatchdogSec (SIGABRT, then SIGKILL)
  daemon.Wait(seconds(10));
  fs::remove_all(dir);
}

// Every board's unit: Type=notify with a watchdog that outlasts the daemon's 2 s liveness
// window, restarted on failure (a missed ping is one), the lasers driven off after it.
TEST(WatchdogTest, EveryUnitIsNotifyWithAWatchdogAndRestarts) {
  int units = 0;
  for (const auto& entry : fs::directory_iterator(kSource / "boards")) {
    const fs::path unit = entry.path() / "mirrorscand.service";
    if (!fs::exists(unit)) continue;
    SCOPED_TRACE(unit.string());
    const std::string text = test_support::ReadFile(unit);
    const auto value = [&](const std::string& key) {
      std::smatch match;
      const std::regex line("(^|\\n)" + key + "=([^\\n]*)");
      return std::regex_search(text, match, line) ? match[2].str() : std::string();
    };
    EXPECT_EQ(value("Type"), "notify");
    EXPECT_EQ(value("NotifyAccess"), "main");
    const std::string watchdog = value("WatchdogSec");
    ASSERT_FALSE(watchdog.empty());
    EXPECT_GE(std::stod(watchdog), 4.0) << watchdog;  // > 2 s window + a ping interval
    EXPECT_TRUE(value("Restart") == "on-failure" || value("Restart") == "always");
    EXPECT_NE(value("ExecStart").find("mirrorscand --board"), std::string::npos);
    ++units;
  }
  EXPECT_GE(units, 3);  // rpi4, rpi5, virtual
}

}  // namespace
}  // namespace mirrorscan

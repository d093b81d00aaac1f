#include "tests/support/daemon.h"

#include <thread>

#include "tests/support/loopback.h"

namespace mirrorscan::test_support {

std::unique_ptr<ChildProcess> StartMirrorscand(const std::vector<std::string>& args,
                                               const std::filesystem::path& log,
                                               const ChildOptions& options) {
  return std::make_unique<ChildProcess>(std::filesystem::path(MIRRORSCAN_BIN_DIR) / "mirrorscand",
                                        args, log, options);
}

bool WaitUntilServing(ChildProcess& daemon, int port, std::chrono::milliseconds deadline) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (HttpRequest(port, "GET", "/api/v1/status").status != 200) {
    if (std::chrono::steady_clock::now() > end || daemon.Exited()) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

}  // namespace mirrorscan::test_support

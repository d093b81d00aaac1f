#pragma once
// This build's mirrorscand as a child process, for the tests that talk to its device API.

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "tests/support/process.h"

namespace mirrorscan::test_support {

// build/bin/mirrorscand with `args`, stdout and stderr to `log`.
std::unique_ptr<ChildProcess> StartMirrorscand(const std::vector<std::string>& args,
                                               const std::filesystem::path& log,
                                               const ChildOptions& options = {});

// Whether the device API on 127.0.0.1:port answers GET /api/v1/status with 200 before
// `deadline` (false as soon as `daemon` has exited).
bool WaitUntilServing(ChildProcess& daemon, int port,
                      std::chrono::milliseconds deadline = std::chrono::seconds(60));

}  // namespace mirrorscan::test_support

#include "firmware/hal/virtual/virtual_line_states.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {
namespace {

[[noreturn]] void Fail(const std::filesystem::path& file, const std::string& problem) {
  throw HardwareError(HardwareError::Kind::kIo,
                      "line state file " + file.string() + ": " + problem);
}

}  // namespace

VirtualLineStates::VirtualLineStates(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0 || ::ftruncate(fd, sizeof(SharedState)) != 0) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    Fail(file, std::strerror(err));
  }
  void* map = ::mmap(nullptr, sizeof(SharedState), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) Fail(file, "cannot map it");
  state_ = new (map) SharedState{};
  state_->magic = kMagic;
}

VirtualLineStates::~VirtualLineStates() { ::munmap(state_, sizeof(SharedState)); }

VirtualLineStates::LineState* VirtualLineStates::Add(const std::string& name, bool high) {
  std::lock_guard lock(mutex_);
  const uint64_t n = state_->count.load();
  if (n >= kMaxLines) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "line state file: more than " + std::to_string(kMaxLines) + " lines");
  }
  LineState& slot = state_->lines[n];
  std::memset(slot.name, 0, sizeof slot.name);
  std::memcpy(slot.name, name.data(), std::min(name.size(), sizeof slot.name - 1));
  slot.high = high ? 1 : 0;
  state_->count = n + 1;
  return &slot;
}

void VirtualLineStates::Record(LineState& slot, bool high, int64_t now_ns) {
  if ((slot.high.load() != 0) == high) return;
  slot.last_change_ns = now_ns;
  slot.high = high ? 1 : 0;
  slot.changes.fetch_add(1);
}

std::vector<VirtualLineStates::Observed> VirtualLineStates::Read(
    const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) Fail(file, std::strerror(errno));
  struct stat info {};
  if (::fstat(fd, &info) != 0 || static_cast<size_t>(info.st_size) < sizeof(SharedState)) {
    ::close(fd);
    Fail(file, "not a line state file (too short)");
  }
  void* map = ::mmap(nullptr, sizeof(SharedState), PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) Fail(file, "cannot map it");
  const auto* state = static_cast<const SharedState*>(map);
  if (state->magic != kMagic) {
    ::munmap(map, sizeof(SharedState));
    Fail(file, "not a line state file");
  }
  std::vector<Observed> lines;
  const uint64_t n = std::min<uint64_t>(state->count.load(), kMaxLines);
  for (uint64_t i = 0; i < n; ++i) {
    const LineState& slot = state->lines[i];
    Observed line;
    line.name.assign(slot.name, strnlen(slot.name, sizeof slot.name));
    line.high = slot.high.load() != 0;
    line.last_change_ns = slot.last_change_ns.load();
    line.changes = slot.changes.load();
    lines.push_back(std::move(line));
  }
  ::munmap(map, sizeof(SharedState));
  return lines;
}

}  // namespace mirrorscan::hal

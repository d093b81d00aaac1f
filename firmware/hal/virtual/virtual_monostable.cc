#include "firmware/hal/virtual/virtual_monostable.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <new>

#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

VirtualMonostable::VirtualMonostable(std::chrono::nanoseconds pulse,
                                     std::optional<std::filesystem::path> state_file)
    : pulse_(pulse), state_(&owned_) {
  owned_.magic = kStateMagic;
  owned_.pulse_ns = pulse.count();
  if (!state_file) return;
  const int fd = ::open(state_file->c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0 || ::ftruncate(fd, sizeof(SharedState)) != 0) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    throw HardwareError(HardwareError::Kind::kIo,
                        "interlock state file " + state_file->string() + ": " + std::strerror(err));
  }
  void* map = ::mmap(nullptr, sizeof(SharedState), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) {
    throw HardwareError(HardwareError::Kind::kIo,
                        "interlock state file " + state_file->string() + ": cannot map it");
  }
  state_ = new (map) SharedState{};
  state_->pulse_ns = pulse.count();
  state_->magic = kStateMagic;
  mapped_bytes_ = sizeof(SharedState);
}

VirtualMonostable::~VirtualMonostable() {
  if (mapped_bytes_ != 0) ::munmap(state_, mapped_bytes_);
}

void VirtualMonostable::SetValue(bool high) {
  if (high && !level_.exchange(true)) {
    state_->last_trigger_ns.store(SteadyNowNs());
    state_->triggers.fetch_add(1);
  } else if (!high) {
    level_ = false;
  }
}

bool VirtualMonostable::GetValue() { return level_; }

std::optional<GpioEdge> VirtualMonostable::WaitEdge(std::chrono::nanoseconds) {
  throw HardwareError(HardwareError::Kind::kInvalidArgument, "the interlock trigger is an output");
}

bool VirtualMonostable::OutputHigh(int64_t now_ns) const {
  const int64_t last = state_->last_trigger_ns.load();
  return last != 0 && now_ns >= last && now_ns - last < pulse_.count();
}

}  // namespace mirrorscan::hal

#include "firmware/hal/virtual/virtual_gpio_line.h"

#include <utility>

#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

VirtualGpioLine::VirtualGpioLine(std::string name, Direction direction, bool initial_high)
    : name_(std::move(name)), direction_(direction), level_(initial_high) {}

void VirtualGpioLine::ThrowIfFailing(const char* what) const {
  if (failing_) {
    throw HardwareError(HardwareError::Kind::kIo,
                        "virtual gpio " + name_ + ": " + what + " failed (injected fault)");
  }
}

void VirtualGpioLine::SetValue(bool high) {
  std::lock_guard lock(mutex_);
  if (direction_ != Direction::kOutput) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "virtual gpio " + name_ + ": SetValue on an input line");
  }
  ThrowIfFailing("set value");
  const int64_t now_ns = SteadyNowNs();
  if (high != level_) last_change_ns_ = now_ns;
  level_ = high;
  history_.push_back(high);
  if (state_slot_ != nullptr) VirtualLineStates::Record(*state_slot_, high, now_ns);
}

void VirtualGpioLine::MirrorTo(std::shared_ptr<VirtualLineStates> states) {
  std::lock_guard lock(mutex_);
  state_slot_ = states->Add(name_, level_);
  states_ = std::move(states);
}

bool VirtualGpioLine::GetValue() {
  std::lock_guard lock(mutex_);
  ThrowIfFailing("get value");
  return level_;
}

std::optional<GpioEdge> VirtualGpioLine::WaitEdge(std::chrono::nanoseconds timeout) {
  std::unique_lock lock(mutex_);
  if (direction_ != Direction::kInput) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "virtual gpio " + name_ + ": WaitEdge on an output line");
  }
  ThrowIfFailing("wait for edge");
  if (!edge_.wait_for(lock, timeout, [this] { return !edges_.empty() || failing_; })) {
    return std::nullopt;
  }
  ThrowIfFailing("wait for edge");
  const GpioEdge e = edges_.front();
  edges_.pop_front();
  return e;
}

bool VirtualGpioLine::driven() const {
  std::lock_guard lock(mutex_);
  return level_;
}

std::vector<bool> VirtualGpioLine::history() const {
  std::lock_guard lock(mutex_);
  return history_;
}

void VirtualGpioLine::InjectEdge(int64_t timestamp_ns, bool high) {
  {
    std::lock_guard lock(mutex_);
    if (high == level_) return;
    level_ = high;
    edges_.push_back({timestamp_ns, high});
  }
  edge_.notify_all();
}

void VirtualGpioLine::SetFailing(bool failing) {
  {
    std::lock_guard lock(mutex_);
    failing_ = failing;
  }
  edge_.notify_all();
}

int64_t VirtualGpioLine::last_change_ns() const {
  std::lock_guard lock(mutex_);
  return last_change_ns_;
}

}  // namespace mirrorscan::hal

#include "firmware/hal/gpiod/gpiod_line.h"

#include <exception>
#include <mutex>

#include <gpiod.hpp>

#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

constexpr const char* kConsumer = "mirrorscand";

struct GpiodLine::Impl {
  gpiod::chip chip;
  gpiod::line line;
  std::mutex mutex;  // one libgpiod call at a time per line
};

void GpiodLine::Fail(const std::string& what, const std::exception& e) const {
  throw HardwareError(HardwareError::Kind::kIo, where_ + ": " + what + ": " + e.what());
}

GpiodLine::GpiodLine(const std::string& chip, unsigned int offset, Direction direction,
                     const std::string& role, bool initial_high)
    : where_("gpio " + chip + " line " + std::to_string(offset) + " (" + role + ")"),
      direction_(direction),
      impl_(std::make_unique<Impl>()) {
  try {
    impl_->chip.open(chip);
  } catch (const std::exception& e) {
    Fail("cannot open chip " + chip, e);
  }
  try {
    impl_->line = impl_->chip.get_line(offset);
    gpiod::line_request request;
    request.consumer = kConsumer;
    request.request_type = direction == Direction::kOutput ? gpiod::line_request::DIRECTION_OUTPUT
                                                           : gpiod::line_request::EVENT_BOTH_EDGES;
    impl_->line.request(request, initial_high ? 1 : 0);
  } catch (const std::exception& e) {
    Fail("cannot request the line", e);
  }
}

GpiodLine::~GpiodLine() {
  try {
    if (impl_->line) impl_->line.release();
  } catch (...) {
  }
}

void GpiodLine::SetValue(bool high) {
  if (direction_ != Direction::kOutput) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument, where_ + ": not an output");
  }
  std::lock_guard lock(impl_->mutex);
  try {
    impl_->line.set_value(high ? 1 : 0);
  } catch (const std::exception& e) {
    Fail("set value", e);
  }
}

bool GpiodLine::GetValue() {
  std::lock_guard lock(impl_->mutex);
  try {
    return impl_->line.get_value() != 0;
  } catch (const std::exception& e) {
    Fail("get value", e);
  }
}

std::optional<GpioEdge> GpiodLine::WaitEdge(std::chrono::nanoseconds timeout) {
  if (direction_ != Direction::kInputWithEdges) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument, where_ + ": no edge events");
  }
  // Not under the mutex: waiting must not block the line's other calls. Only the
  // button's thread waits on an input line.
  try {
    if (!impl_->line.event_wait(timeout)) return std::nullopt;
    const gpiod::line_event event = impl_->line.event_read();
    return GpioEdge{event.timestamp.count(), event.event_type == gpiod::line_event::RISING_EDGE};
  } catch (const std::exception& e) {
    Fail("wait for edge", e);
  }
}

}  // namespace mirrorscan::hal

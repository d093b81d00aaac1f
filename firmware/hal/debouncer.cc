#include "firmware/hal/debouncer.h"

#include <algorithm>

namespace mirrorscan::hal {

Debouncer::Debouncer(int64_t debounce_ns, bool initial_active, int64_t start_ns)
    : debounce_ns_(std::max<int64_t>(debounce_ns, 0)),
      stable_(initial_active),
      raw_(initial_active),
      raw_since_(start_ns) {}

std::optional<ButtonEvent> Debouncer::OnChange(int64_t timestamp_ns, bool active) {
  const int64_t t = std::max(timestamp_ns, raw_since_);
  std::optional<ButtonEvent> event = Advance(t);
  if (active != raw_) {
    raw_ = active;
    raw_since_ = t;
  }
  return event;
}

std::optional<ButtonEvent> Debouncer::Advance(int64_t now_ns) {
  if (raw_ == stable_ || now_ns - raw_since_ < debounce_ns_) return std::nullopt;
  stable_ = raw_;
  return ButtonEvent{stable_ ? ButtonEvent::Type::kPressed : ButtonEvent::Type::kReleased,
                     raw_since_};
}

std::optional<int64_t> Debouncer::deadline_ns() const {
  if (raw_ == stable_) return std::nullopt;
  return raw_since_ + debounce_ns_;
}

}  // namespace mirrorscan::hal

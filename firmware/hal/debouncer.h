#pragma once

#include <cstdint>
#include <optional>

#include "firmware/hal/button.h"

namespace mirrorscan::hal {

// Debounces one input on timestamps alone (no clock, no threads): a new level counts once
// it has stayed unchanged for at least `debounce_ns`; a level that flips back within the
// window is ignored. Works on active levels (true = pressed); polarity is applied before.
class Debouncer {
 public:
  explicit Debouncer(int64_t debounce_ns, bool initial_active = false, int64_t start_ns = 0);

  // A raw level change at `timestamp_ns`. First confirms the level that held until now if
  // it lasted long enough (that event is returned). An edge older than the previous one
  // counts as simultaneous with it; an edge to the level it already has is ignored.
  std::optional<ButtonEvent> OnChange(int64_t timestamp_ns, bool active);
  // Time passed without an edge: confirms the pending level if it has held for
  // debounce_ns by `now_ns`.
  std::optional<ButtonEvent> Advance(int64_t now_ns);

  // When the pending level would be confirmed if no edge came; nullopt if none pends.
  std::optional<int64_t> deadline_ns() const;
  bool active() const { return stable_; }

 private:
  int64_t debounce_ns_;
  bool stable_;        // the debounced level
  bool raw_;           // the last raw level
  int64_t raw_since_;  // when raw_ began
};

}  // namespace mirrorscan::hal

#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace mirrorscan::hal {

// A debounced button event. timestamp_ns (steady clock) is the edge that began the
// level that then stayed stable for the debounce time, i.e. when the press really
// happened; the event is delivered debounce_ms later at the earliest.
struct ButtonEvent {
  enum class Type { kPressed, kReleased };
  Type type = Type::kPressed;
  int64_t timestamp_ns = 0;
};

std::string ToString(const ButtonEvent& event);

// The pushbutton. Events arrive through a callback called on the button's own thread.
// The callback must only enqueue (push to a queue, notify): it must not block, must not
// call back into the Button, and must not throw.
class Button {
 public:
  using Callback = std::function<void(const ButtonEvent&)>;

  virtual ~Button() = default;

  // Starts watching the line and delivering events to `callback`. Throws HardwareError
  // if the line cannot be read; a second Start() without Stop() is kInvalidArgument.
  virtual void Start(Callback callback) = 0;
  // Stops watching; no callback runs after Stop() returns. Never throws.
  virtual void Stop() noexcept = 0;
  // The debounced state.
  virtual bool pressed() const = 0;
};

}  // namespace mirrorscan::hal

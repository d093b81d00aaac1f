#include "firmware/hal/gpio_devices.h"

#include <algorithm>
#include <exception>
#include <limits>
#include <utility>

namespace mirrorscan::hal {

std::string ToString(LedPattern pattern) {
  switch (pattern) {
    case LedPattern::kOff:
      return "off";
    case LedPattern::kOn:
      return "on";
    case LedPattern::kBlinkSlow:
      return "blink-slow";
    case LedPattern::kBlinkFast:
      return "blink-fast";
    case LedPattern::kFault:
      return "fault";
  }
  return "?";
}

std::string ToString(const ButtonEvent& event) {
  return std::string(event.type == ButtonEvent::Type::kPressed ? "pressed" : "released") + " at " +
         std::to_string(event.timestamp_ns) + " ns";
}

// ---- GpioLaserBank ----

GpioLaserBank::GpioLaserBank(std::vector<OwnedGpioLine> lines) : owned_(std::move(lines)) {
  if (owned_.empty() || owned_.size() > 3) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "laser bank: 1 to 3 lasers, got " + std::to_string(owned_.size()));
  }
  for (OwnedGpioLine& l : owned_) lines_.emplace_back(*l.line, l.active_low);
  states_.assign(lines_.size(), false);
  if (!SafeOff()) {
    throw HardwareError(HardwareError::Kind::kIo, "laser bank: cannot switch the lasers off");
  }
}

GpioLaserBank::~GpioLaserBank() { SafeOff(); }

void GpioLaserBank::Set(int laser, bool on) {
  if (laser < 0 || laser >= count()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "laser bank: no laser " + std::to_string(laser) + " (have " +
                            std::to_string(count()) + ")");
  }
  std::lock_guard lock(mutex_);
  // Mark it on before trying, so a failed write never leaves states() claiming "off".
  if (on) states_[laser] = true;
  lines_[laser].SetActive(on);
  states_[laser] = on;
}

void GpioLaserBank::SetAll(bool on) {
  if (!on) {
    if (!SafeOff()) {
      throw HardwareError(HardwareError::Kind::kIo, "laser bank: cannot switch every laser off");
    }
    return;
  }
  std::lock_guard lock(mutex_);
  for (size_t i = 0; i < lines_.size(); ++i) {
    states_[i] = true;
    lines_[i].SetActive(true);
  }
}

std::vector<bool> GpioLaserBank::states() const {
  std::lock_guard lock(mutex_);
  return states_;
}

bool GpioLaserBank::SafeOff() noexcept {
  std::lock_guard lock(mutex_);
  bool all_off = true;
  for (size_t i = 0; i < lines_.size(); ++i) {
    try {
      lines_[i].SetActive(false);
      states_[i] = false;
    } catch (...) {  // keep going: every other line must still go off
      all_off = false;
    }
  }
  return all_off;
}

// ---- GpioLed ----

LedPhase LedPhaseAt(LedPattern pattern, int64_t elapsed_ns) {
  constexpr int64_t kMs = 1'000'000;
  constexpr int64_t kNever = std::numeric_limits<int64_t>::max();
  // Alternating lit/dark segments, starting lit, in ms.
  static constexpr int64_t kSlow[] = {500, 500};
  static constexpr int64_t kFast[] = {100, 100};
  static constexpr int64_t kFault[] = {100, 100, 100, 700};
  const int64_t* seg = nullptr;
  size_t n = 0;
  switch (pattern) {
    case LedPattern::kOff:
      return {false, kNever};
    case LedPattern::kOn:
      return {true, kNever};
    case LedPattern::kBlinkSlow:
      seg = kSlow;
      n = 2;
      break;
    case LedPattern::kBlinkFast:
      seg = kFast;
      n = 2;
      break;
    case LedPattern::kFault:
      seg = kFault;
      n = 4;
      break;
  }
  int64_t period = 0;
  for (size_t i = 0; i < n; ++i) period += seg[i] * kMs;
  const int64_t e = std::max<int64_t>(elapsed_ns, 0);
  const int64_t start = e - e % period;
  int64_t t = start;
  for (size_t i = 0; i < n; ++i) {
    t += seg[i] * kMs;
    if (e < t) return {i % 2 == 0, t};
  }
  return {true, t};  // not reached
}

GpioLed::GpioLed(OwnedGpioLine line)
    : owned_(std::move(line)), line_(*owned_.line, owned_.active_low) {
  line_.SetActive(false);
  thread_ = std::thread([this] { Run(); });
}

GpioLed::~GpioLed() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
  try {
    line_.SetActive(false);
  } catch (...) {
  }
}

void GpioLed::Set(LedPattern pattern) {
  std::lock_guard lock(mutex_);
  pattern_ = pattern;
  since_ns_ = SteadyNowNs();
  line_.SetActive(LedPhaseAt(pattern, 0).lit);
  changed_.notify_all();
}

LedPattern GpioLed::pattern() const {
  std::lock_guard lock(mutex_);
  return pattern_;
}

void GpioLed::Run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    const LedPhase phase = LedPhaseAt(pattern_, SteadyNowNs() - since_ns_);
    try {
      line_.SetActive(phase.lit);
    } catch (...) {  // retried at the next change; Set() reports errors to the caller
    }
    if (phase.next_change_ns == std::numeric_limits<int64_t>::max()) {
      changed_.wait(lock);
    } else {
      const auto at = std::chrono::steady_clock::time_point(
          std::chrono::nanoseconds(since_ns_ + phase.next_change_ns));
      changed_.wait_until(lock, at);
    }
  }
}

// ---- GpioButton ----

GpioButton::GpioButton(OwnedGpioLine line, std::chrono::milliseconds debounce, NowFn now)
    : owned_(std::move(line)),
      line_(*owned_.line, owned_.active_low),
      debounce_ns_(std::chrono::nanoseconds(debounce).count()),
      now_(std::move(now)) {}

GpioButton::~GpioButton() { Stop(); }

std::vector<ButtonEvent> GpioButton::Step(std::chrono::nanoseconds max_wait) {
  std::vector<ButtonEvent> events;
  if (!debouncer_) {
    const bool active = line_.IsActive();
    debouncer_ = std::make_unique<Debouncer>(debounce_ns_, active, now_());
    pressed_ = active;
  }
  int64_t wait = max_wait.count();
  if (const auto deadline = debouncer_->deadline_ns()) {
    wait = std::clamp<int64_t>(*deadline - now_(), 0, wait);
  }
  std::optional<ActiveLevelLine::Change> change = line_.WaitChange(std::chrono::nanoseconds(wait));
  // Read the clock before draining: every edge up to `now` is then in the queue, so the
  // level is never confirmed past an edge that is still queued.
  const int64_t now = now_();
  while (change) {
    // Edge times come from the line's clock; one far off `now` (e.g. a kernel that
    // stamps with CLOCK_REALTIME) is taken as now, so debouncing still ends.
    int64_t t = change->timestamp_ns;
    if (t > now || now - t > 10'000'000'000) t = now;
    if (auto e = debouncer_->OnChange(t, change->active)) events.push_back(*e);
    change = line_.WaitChange(std::chrono::nanoseconds(0));
  }
  if (auto e = debouncer_->Advance(now)) events.push_back(*e);
  pressed_ = debouncer_->active();
  return events;
}

void GpioButton::Start(Callback callback) {
  if (thread_.joinable()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument, "button: already started");
  }
  for (const ButtonEvent& e : Step(std::chrono::nanoseconds(0)))
    callback(e);  // throws if
                  // unreadable
  stop_ = false;
  thread_ = std::thread([this, cb = std::move(callback)] {
    while (!stop_) {
      try {
        for (const ButtonEvent& e : Step(std::chrono::milliseconds(20))) cb(e);
      } catch (const std::exception& e) {
        {
          std::lock_guard lock(error_mutex_);
          last_error_ = e.what();
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    }
  });
}

void GpioButton::Stop() noexcept {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

std::string GpioButton::last_error() const {
  std::lock_guard lock(error_mutex_);
  return last_error_;
}

GpioLaserInterlock::GpioLaserInterlock(OwnedGpioLine trigger, std::chrono::milliseconds pulse)
    : trigger_(std::move(trigger)), pulse_(pulse) {}

void GpioLaserInterlock::Kick() noexcept {
  try {
    trigger_.line->SetValue(ActiveLevelLine::ToPhysical(true, trigger_.active_low));
    trigger_.line->SetValue(ActiveLevelLine::ToPhysical(false, trigger_.active_low));
  } catch (const std::exception&) {
    // No pulse: the monostable runs out and the lasers go dark, as they should.
  }
}

}  // namespace mirrorscan::hal

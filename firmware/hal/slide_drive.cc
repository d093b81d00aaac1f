#include "firmware/hal/slide_drive.h"

#include <sstream>
#include <thread>

namespace mirrorscan::hal {

std::string ToString(const SlideStatus& status) {
  std::ostringstream out;
  out << (status.enabled ? "enabled" : "disabled") << (status.homed ? ", homed" : ", not homed")
      << (status.moving ? ", moving" : ", still");
  if (status.fault) out << ", fault " << status.fault_code;
  return out.str();
}

void SlideDrive::Home(std::chrono::nanoseconds timeout, std::chrono::nanoseconds poll) {
  const uint64_t generation = stop_generation_.load(std::memory_order_relaxed);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  StartHome();
  while (true) {
    const SlideStatus status = Status();
    if (status.fault) {
      throw HardwareError(
          HardwareError::Kind::kFault,
          "slide drive: fault " + std::to_string(status.fault_code) + " while homing");
    }
    if (status.homed && !status.moving) return;
    if (stop_generation_.load(std::memory_order_relaxed) != generation) {
      throw HardwareError(HardwareError::Kind::kAborted,
                          "slide drive: homing interrupted by Stop()");
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      std::string stopped = "stopped";
      try {
        DoStop();
      } catch (const HardwareError& e) {
        stopped = std::string("stopping failed too: ") + e.what();
      }
      throw HardwareError(HardwareError::Kind::kTimeout,
                          "slide drive: not homed after " +
                              std::to_string(std::chrono::duration<double>(timeout).count()) +
                              " s (" + ToString(status) + "); " + stopped);
    }
    std::this_thread::sleep_for(poll);
  }
}

}  // namespace mirrorscan::hal

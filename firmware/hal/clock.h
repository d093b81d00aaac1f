#pragma once

#include <chrono>
#include <cstdint>

namespace mirrorscan::hal {

// The firmware's timestamps: integer nanoseconds on the steady clock (DESIGN.md).
inline int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace mirrorscan::hal

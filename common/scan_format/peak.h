#pragma once

#include <cstdint>

namespace mirrorscan {

// One laser peak: image column u, sub-pixel row v (integer = pixel centre), quality.
struct Peak {
  uint16_t u = 0;
  float v = 0, intensity = 0, width = 0, score = 0;
};

}  // namespace mirrorscan

#pragma once

#include <cstdint>

namespace mirrorscan {

// One laser peak: where a stripe crosses an image column.
struct Peak {
  uint16_t u = 0;       // image column
  float v = 0;          // sub-pixel row of the stripe centre (integer = pixel centre)
  float intensity = 0;  // peak height above the local background, DN
  float width = 0;      // stripe width (FWHM) in pixels
  float score = 0;      // extractor's confidence in [0, 1]

  bool operator==(const Peak&) const = default;
};

}  // namespace mirrorscan

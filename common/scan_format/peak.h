#pragma once

#include <cstdint>

namespace mirrorscan {

// One laser-stripe peak in one image column: shared by the peak extractor and the .mscan
// archive, so the archive stores exactly what the extractor produced.
struct Peak {
  uint16_t u = 0;       // image column
  float v = 0;          // sub-pixel row of the stripe centre
  float intensity = 0;  // peak grey value
  float width = 0;      // stripe width in pixels
  float score = 0;      // extractor's confidence

  bool operator==(const Peak&) const = default;
};

}  // namespace mirrorscan

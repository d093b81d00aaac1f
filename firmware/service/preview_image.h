#pragma once

// The web page's live camera preview (GET /api/v1/preview): a frame shrunk by a whole
// factor (box average), the detected laser peaks drawn in red, as an 8-bit palette PNG
// (indices 0..254 gray, 255 red), compressed with zlib. A 1024x768 frame at scale 2 is
// a 512x384 image of ~100 kB: small enough for a once-a-second refresh over Wi-Fi.

#include <cstdint>
#include <string>
#include <vector>

#include "common/scan_format/peak.h"

namespace mirrorscan::service {

inline constexpr uint8_t kPreviewPeakIndex = 255;  // the palette's red

// `pixels` is width x height 8-bit gray, row-major (stride = width); scale >= 1.
// Throws std::invalid_argument for a malformed frame.
std::string RenderPreviewPng(const std::vector<uint8_t>& pixels, int width, int height,
                             const std::vector<Peak>& peaks, int scale);

}  // namespace mirrorscan::service

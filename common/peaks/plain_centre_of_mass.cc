#include "common/peaks/peaks.h"

namespace mirrorscan {

void PlainCentreOfMass::Extract(const ImageView& image, int threshold_dn, std::vector<Peak>* out) {
  out->clear();
  const int width = image.width;
  sum_.assign(width, 0);
  moment_.assign(width, 0);
  first_.assign(width, 0);
  top_.assign(width, 0);
  const auto emit = [&](int u, int end_row) {
    Peak peak;
    peak.u = static_cast<uint16_t>(u);
    peak.v = static_cast<float>(moment_[u]) / static_cast<float>(sum_[u]);
    peak.intensity = static_cast<float>(top_[u]);
    peak.width = static_cast<float>(end_row - first_[u]);
    peak.score = 1.0f;
    out->push_back(peak);
    sum_[u] = moment_[u] = top_[u] = 0;
  };
  for (int r = 0; r < image.height; ++r) {
    const uint8_t* row = image.data + static_cast<ptrdiff_t>(r) * image.stride;
    for (int u = 0; u < width; ++u) {
      const int excess = row[u] - threshold_dn;
      if (excess > 0) {
        if (sum_[u] == 0) first_[u] = static_cast<uint16_t>(r);
        sum_[u] += static_cast<uint32_t>(excess);
        moment_[u] += static_cast<uint32_t>(excess * r);
        if (excess > top_[u]) top_[u] = static_cast<uint16_t>(excess);
      } else if (sum_[u] != 0) {
        emit(u, r);
      }
    }
  }
  for (int u = 0; u < width; ++u)
    if (sum_[u] != 0) emit(u, image.height);
}

}  // namespace mirrorscan

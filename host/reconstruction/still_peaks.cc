#include "host/reconstruction/still_peaks.h"

#include <cmath>
#include <vector>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {

size_t MarkStillPeaks(int threads, PeakTable* table) {
  const size_t frames = table->next_frame.size();
  std::vector<int32_t> previous(frames, -1);
  for (size_t f = 0; f < frames; ++f)
    if (table->next_frame[f] >= 0) previous[table->next_frame[f]] = static_cast<int32_t>(f);
  // Whether frame g holds a peak in column u within kStillPx of row v.
  auto holds = [&](int32_t g, int u, float v) {
    const auto [first, last] = table->Column(static_cast<uint32_t>(g), u);
    for (uint32_t j = first; j < last; ++j)
      if (std::abs(table->peaks[j].v - v) <= kStillPx) return true;
    return false;
  };
  std::vector<size_t> marked(ChunkCount(frames, threads), 0);
  ForEachChunk(frames, threads, [&](size_t c, size_t begin, size_t end) {
    for (size_t f = begin; f < end; ++f) {
      if (!table->used[f]) continue;
      for (uint32_t i = table->frame_first[f]; i < table->frame_first[f + 1]; ++i) {
        PeakState& p = table->peaks[i];
        int found = 0;
        int32_t g = table->next_frame[f];
        for (int k = 0; k < kStillReach && g >= 0 && found < kStillFrames; ++k) {
          found += holds(g, p.u, p.v);
          g = table->next_frame[g];
        }
        g = previous[f];
        for (int k = 0; k < kStillReach && g >= 0 && found < kStillFrames; ++k) {
          found += holds(g, p.u, p.v);
          g = previous[g];
        }
        if (found >= kStillFrames) {
          p.still = true;
          ++marked[c];
        }
      }
    }
  });
  size_t total = 0;
  for (size_t n : marked) total += n;
  return total;
}

}  // namespace mirrorscan::reconstruction

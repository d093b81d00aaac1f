#include "host/reconstruction/still_peaks.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {
namespace {

// Marks the peaks in column u of one camera's frames (in time order) whose row recurs in
// kRecurringVisits separate visits and which are no brighter than the peaks there.
size_t MarkRecurring(const std::vector<uint32_t>& frames, int u, PeakTable* table) {
  struct Entry {
    float v;
    int32_t rank;  // the frame's place among the camera's frames
    uint32_t peak;
  };
  std::vector<Entry> entries;
  for (size_t r = 0; r < frames.size(); ++r) {
    const auto [first, last] = table->Column(frames[r], u);
    for (uint32_t j = first; j < last; ++j)
      entries.push_back({table->peaks[j].v, static_cast<int32_t>(r), j});
  }
  if (entries.size() < static_cast<size_t>(kRecurringVisits)) return 0;
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.v < b.v; });
  size_t marked = 0, lo = 0, hi = 0;
  std::vector<int32_t> ranks;
  std::vector<float> brightness;
  for (size_t i = 0; i < entries.size(); ++i) {
    while (entries[i].v - entries[lo].v > kStillPx) ++lo;
    while (hi < entries.size() && entries[hi].v - entries[i].v <= kStillPx) ++hi;
    if (hi - lo < static_cast<size_t>(kRecurringVisits)) continue;
    ranks.clear();
    brightness.clear();
    for (size_t k = lo; k < hi; ++k) {
      ranks.push_back(entries[k].rank);
      brightness.push_back(table->peaks[entries[k].peak].intensity);
    }
    std::sort(ranks.begin(), ranks.end());
    int visits = 1;
    for (size_t k = 1; k < ranks.size(); ++k) visits += ranks[k] - ranks[k - 1] > kVisitGapFrames;
    if (visits < kRecurringVisits) continue;
    const auto mid = brightness.begin() + brightness.size() / 2;
    std::nth_element(brightness.begin(), mid, brightness.end());
    PeakState& p = table->peaks[entries[i].peak];
    if (p.still || p.intensity > kRecurringBrightness * *mid) continue;
    p.still = true;
    ++marked;
  }
  return marked;
}

}  // namespace

size_t MarkStillPeaks(int threads, PeakTable* table) {
  const size_t frames = table->next_frame.size();
  std::vector<int32_t> previous(frames, -1);
  for (size_t f = 0; f < frames; ++f)
    if (table->next_frame[f] >= 0) previous[table->next_frame[f]] = static_cast<int32_t>(f);
  // The intensity of frame g's peak in column u within kStillPx of row v, or -1.
  auto held = [&](int32_t g, int u, float v) {
    const auto [first, last] = table->Column(static_cast<uint32_t>(g), u);
    for (uint32_t j = first; j < last; ++j)
      if (std::abs(table->peaks[j].v - v) <= kStillPx) return table->peaks[j].intensity;
    return -1.0f;
  };
  std::vector<size_t> marked(ChunkCount(frames, threads), 0);
  ForEachChunk(frames, threads, [&](size_t c, size_t begin, size_t end) {
    std::vector<float> found;
    for (size_t f = begin; f < end; ++f) {
      if (!table->used[f]) continue;
      for (uint32_t i = table->frame_first[f]; i < table->frame_first[f + 1]; ++i) {
        PeakState& p = table->peaks[i];
        found.clear();
        for (const bool forward : {true, false}) {
          int32_t g = forward ? table->next_frame[f] : previous[f];
          for (int k = 0;
               k < kStillReach && g >= 0 && found.size() < static_cast<size_t>(kStillFrames); ++k) {
            if (const float intensity = held(g, p.u, p.v); intensity >= 0)
              found.push_back(intensity);
            g = forward ? table->next_frame[g] : previous[g];
          }
        }
        if (found.size() < static_cast<size_t>(kStillFrames)) continue;
        // A laser crossing the edge's row is brighter than the edge.
        std::sort(found.begin(), found.end());
        if (p.intensity > kRecurringBrightness * found[found.size() / 2]) continue;
        p.still = true;
        ++marked[c];
      }
    }
  });
  size_t total = 0;
  for (size_t n : marked) total += n;

  // Each camera's frames in time order, then every (camera, column).
  std::vector<std::vector<uint32_t>> cameras;
  for (size_t f = 0; f < frames; ++f) {
    if (!table->used[f] || previous[f] >= 0) continue;
    cameras.emplace_back();
    for (int32_t g = static_cast<int32_t>(f); g >= 0; g = table->next_frame[g])
      cameras.back().push_back(static_cast<uint32_t>(g));
  }
  const size_t columns = static_cast<size_t>(table->columns);
  const size_t tasks = cameras.size() * columns;
  std::vector<size_t> recurring(ChunkCount(tasks, threads), 0);
  ForEachChunk(tasks, threads, [&](size_t c, size_t begin, size_t end) {
    for (size_t t = begin; t < end; ++t)
      recurring[c] += MarkRecurring(cameras[t / columns], static_cast<int>(t % columns), table);
  });
  for (size_t n : recurring) total += n;
  return total;
}

}  // namespace mirrorscan::reconstruction

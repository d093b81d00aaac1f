#include "host/reconstruction/rules/column_count.h"

#include <array>
#include <cstdint>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/laser_sequence.h"

namespace mirrorscan::reconstruction {

void DecideByColumnCount(PeakTable* table, const Hypotheses& hyp, int laser_count, int threads) {
  if (laser_count < 2) return;
  const size_t frames = table->frame_first.size() - 1;
  // A frame decides only its own peaks.
  ParallelFor(frames, threads, [&](size_t frames_begin, size_t frames_end) {
    for (size_t f = frames_begin; f < frames_end; ++f) {
      const uint32_t begin = table->frame_first[f], end = table->frame_first[f + 1];
      for (uint32_t i = begin; i < end;) {
        uint32_t run_end = i;
        while (run_end < end && table->peaks[run_end].u == table->peaks[i].u) ++run_end;
        for (uint8_t region = 0; region < 3; ++region) {
          std::array<uint32_t, kMaxLasers> members{};
          int n = 0;
          for (uint32_t j = i; j < run_end; ++j) {
            const PeakState& p = table->peaks[j];
            if (p.region != region || p.hypotheses == 0 || p.panel) continue;
            if (n == laser_count) {
              n = laser_count + 1;
              break;
            }
            members[n++] = j;
          }
          if (n != laser_count) continue;
          // Rows ascend within a column: the first is the highest laser, and every row is
          // the same view (a mirror keeps up and down). A peak of the column decided already
          // with another laser or view, or rows whose lasers only other views have, say the
          // count is not the lasers: an arm in front of a mirror stands in for one of the
          // mirror's stripes.
          std::array<int, kMaxLasers> pick{};
          int view = -1;
          bool agrees = true;
          for (int r = 0; r < n && agrees; ++r) {
            const PeakState& p = table->peaks[members[r]];
            const int laser = laser_count - 1 - r;
            int count = 0;
            pick[r] = -1;
            for (int h = 0; h < p.hypotheses; ++h) {
              if (hyp[p.first_hypothesis + h].key % kMaxLasers == laser) {
                pick[r] = h;
                ++count;
              }
            }
            if (p.chosen >= 0) {
              pick[r] = p.chosen;
              count = 1;
            }
            if (count != 1) {
              pick[r] = -1;  // no single hypothesis of this laser: the row decides nothing
              continue;
            }
            const int key = hyp[p.first_hypothesis + pick[r]].key;
            // The laser sequence at the pixel says another laser: the count is not the lasers.
            if (key % kMaxLasers != laser || (view >= 0 && key / kMaxLasers != view) ||
                !(SequenceAllows(&hyp[p.first_hypothesis], p.hypotheses) >> pick[r] & 1u) ||
                SequenceRefutes(&hyp[p.first_hypothesis], p.hypotheses, pick[r]))
              agrees = false;
            view = key / kMaxLasers;
          }
          if (!agrees) continue;
          for (int r = 0; r < n; ++r) {
            PeakState& p = table->peaks[members[r]];
            if (p.rule != Rule::kNone || pick[r] < 0) continue;
            p.chosen = static_cast<int16_t>(pick[r]);
            p.rule = Rule::kColumnCount;
          }
        }
        i = run_end;
      }
    }
  });
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/peak_table.h"

#include <algorithm>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

PeakTable ReadPeaks(const ScanArchive& archive, int threads, ReconstructSummary* summary) {
  PeakTable table;
  std::vector<bool>& use_frame = table.used;
  use_frame.resize(archive.frames.size());
  for (size_t f = 0; f < archive.frames.size(); ++f) {
    use_frame[f] = archive.frames[f].lasers_on && !archive.frames[f].peaks.empty();
    if (use_frame[f]) {
      ++summary->frames;
      summary->peaks += archive.frames[f].peaks.size();
    }
  }
  if (summary->peaks == 0) {
    throw ReconstructError(archive.frames.empty()
                               ? "the archive holds no frames (" + archive.report.message + ")"
                               : "no frame with the lasers on has any peak");
  }
  const size_t n = archive.frames.size();
  table.frame_first.assign(n + 1, 0);
  size_t total = 0;
  for (size_t f = 0; f < n; ++f) {
    table.frame_first[f] = static_cast<uint32_t>(total);
    if (use_frame[f]) total += archive.frames[f].peaks.size();
  }
  table.frame_first[n] = static_cast<uint32_t>(total);
  table.peaks.resize(total);
  for (size_t f = 0; f < n; ++f) {
    if (!use_frame[f]) continue;
    for (const Peak& p : archive.frames[f].peaks) table.columns = std::max(table.columns, p.u + 1);
  }
  const size_t stride = table.columns + 1;
  table.column_first.resize(n * stride);
  ParallelFor(n, threads, [&](size_t begin, size_t end) {
    for (size_t f = begin; f < end; ++f) {
      const auto first = table.peaks.begin() + table.frame_first[f];
      const auto last = table.peaks.begin() + table.frame_first[f + 1];
      if (use_frame[f]) {
        auto out = first;
        for (const Peak& p : archive.frames[f].peaks) {
          out->frame = static_cast<uint32_t>(f);
          out->u = p.u;
          out->v = p.v;
          out->score = p.score;
          out->intensity = p.intensity;
          ++out;
        }
        std::sort(first, last, [](const PeakState& a, const PeakState& b) {
          return a.u != b.u ? a.u < b.u : a.v < b.v;
        });
      }
      uint32_t i = table.frame_first[f];
      for (int u = 0; u <= table.columns; ++u) {
        while (i < table.frame_first[f + 1] && table.peaks[i].u < u) ++i;
        table.column_first[f * stride + u] = i;
      }
    }
  });
  // Frames of one camera in time order.
  table.next_frame.assign(n, -1);
  std::vector<uint32_t> order;
  for (size_t f = 0; f < n; ++f)
    if (use_frame[f]) order.push_back(static_cast<uint32_t>(f));
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    const FrameRecord& fa = archive.frames[a];
    const FrameRecord& fb = archive.frames[b];
    return fa.camera != fb.camera ? fa.camera < fb.camera : fa.timestamp_ns < fb.timestamp_ns;
  });
  for (size_t i = 0; i + 1 < order.size(); ++i) {
    if (archive.frames[order[i]].camera == archive.frames[order[i + 1]].camera)
      table.next_frame[order[i]] = static_cast<int32_t>(order[i + 1]);
  }
  return table;
}

}  // namespace mirrorscan::reconstruction

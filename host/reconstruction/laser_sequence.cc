#include "host/reconstruction/laser_sequence.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {

namespace {

// The same surface point lit by another laser one or more spacings of travel later: within
// half a frame's travel of the moment (the frames either side are looked at), the stripe is
// within a row or two of where this one crossed the pixel.
constexpr double kRowsPx = 2.0;

// The plane's height above a point's (x, y); the planes are near horizontal.
double HeightAt(const Plane& plane, const Eigen::Vector3d& point) {
  return -(plane.normal.x() * point.x() + plane.normal.y() * point.y() + plane.offset) /
         plane.normal.z();
}

}  // namespace

uint32_t SequenceAllows(const Hypothesis* first, int count) {
  // Per view: a pixel at a silhouette sees two surfaces at different moments, each with its
  // own sequence, so only the lasers of one view are weighed against each other.
  std::array<int, kViews> best{};
  for (int h = 0; h < count; ++h)
    if (!first[h].Background() && first[h].sequence_missing == 0) {
      int& b = best[first[h].key / kMaxLasers];
      b = std::max<int>(b, first[h].sequence_seen);
    }
  uint32_t allowed = 0;
  for (int h = 0; h < count; ++h) {
    const int b = best[first[h].key / kMaxLasers];
    if (b == 0 || first[h].Background() ||
        (first[h].sequence_missing == 0 && first[h].sequence_seen == b))
      allowed |= 1u << h;
  }
  return allowed;
}

bool SequenceRefutes(const Hypothesis* first, int count, int h) {
  if (first[h].sequence_missing == 0) return false;
  const int view = first[h].key / kMaxLasers;
  return std::any_of(first, first + count, [&](const Hypothesis& x) {
    return !x.Background() && x.sequence_missing == 0 &&
           (x.key / kMaxLasers == view || x.sequence_seen > 0);
  });
}

void MarkLaserSequence(const PeakTable& table, const LaserPlanes& planes, int threads,
                       Hypotheses* hyp) {
  if (planes.count < 2) return;
  const size_t frames = table.frame_first.size() - 1;
  // Each camera's frames with planes, in time order (the table's next_frame chains).
  std::vector<bool> has_previous(frames, false);
  for (size_t f = 0; f < frames; ++f)
    if (table.next_frame[f] >= 0) has_previous[table.next_frame[f]] = true;
  std::vector<std::vector<uint32_t>> sequence;
  std::vector<int32_t> sequence_of(frames, -1);
  for (size_t f = 0; f < frames; ++f) {
    if (!table.used[f] || has_previous[f]) continue;
    std::vector<uint32_t> list;
    for (int32_t g = static_cast<int32_t>(f); g >= 0; g = table.next_frame[g])
      if (planes.valid[g]) list.push_back(static_cast<uint32_t>(g));
    for (uint32_t g : list) sequence_of[g] = static_cast<int32_t>(sequence.size());
    sequence.push_back(std::move(list));
  }
  // Whether frame g has a peak in column u within rows_px of v.
  const auto peak_near = [&](uint32_t g, int u, double v) {
    const auto [lo, hi] = table.Column(g, u);
    for (uint32_t i = lo; i < hi; ++i)
      if (std::abs(table.peaks[i].v - v) <= kRowsPx) return true;
    return false;
  };
  ParallelFor(frames, threads, [&](size_t frames_begin, size_t frames_end) {
    for (size_t f = frames_begin; f < frames_end; ++f) {
      if (sequence_of[f] < 0) continue;
      const std::vector<uint32_t>& list = sequence[sequence_of[f]];
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        if (p.hypotheses < 2) continue;
        for (int h = 0; h < p.hypotheses; ++h) {
          Hypothesis& x = (*hyp)[p.first_hypothesis + h];
          if (x.Background()) continue;
          const int laser = x.key % kMaxLasers;
          for (int other = 0; other < planes.count; ++other) {
            if (other == laser) continue;
            // The first frame whose plane of that laser is above the point: the moment lies
            // between it and the frame before.
            const auto after = std::partition_point(list.begin(), list.end(), [&](uint32_t g) {
              return HeightAt(planes.per_frame[g][other], x.point) < x.point.z();
            });
            if (after == list.begin() || after == list.end()) continue;  // not in the sweep
            if (peak_near(*(after - 1), p.u, p.v) || peak_near(*after, p.u, p.v)) {
              ++x.sequence_seen;
            } else {
              ++x.sequence_missing;
            }
          }
        }
      }
    }
  });
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/rules/stereo.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <utility>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/laser_sequence.h"

namespace mirrorscan::reconstruction {

namespace {

// Each frame's hypotheses of one laser by the 2D cell of their point (the laser plane gives
// the height), so another camera's hypotheses near a point are a few binary searches away.
class HypothesisIndex {
 public:
  HypothesisIndex(const PeakTable& table, const Hypotheses& hyp) {
    const size_t frames = table.frame_first.size() - 1;
    first_.assign(frames * kMaxLasers + 1, 0);
    for (size_t f = 0; f < frames; ++f)
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        for (int h = 0; h < p.hypotheses; ++h)
          ++first_[f * kMaxLasers + hyp[p.first_hypothesis + h].key % kMaxLasers + 1];
      }
    for (size_t s = 1; s < first_.size(); ++s) first_[s] += first_[s - 1];
    entries_.resize(first_.back());
    std::vector<uint32_t> fill(first_.begin(), first_.end() - 1);
    for (size_t f = 0; f < frames; ++f)
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        for (int h = 0; h < p.hypotheses; ++h) {
          const uint32_t at = p.first_hypothesis + h;
          const Eigen::Vector3d& x = hyp[at].point;
          entries_[fill[f * kMaxLasers + hyp[at].key % kMaxLasers]++] = {Cell(x.x(), x.y()), at};
        }
      }
    for (size_t s = 0; s + 1 < first_.size(); ++s)
      std::sort(entries_.begin() + first_[s], entries_.begin() + first_[s + 1],
                [](const Entry& a, const Entry& b) { return a.cell < b.cell; });
  }

  // Whether the frame has a hypothesis of this laser within radius of the point.
  bool AnyNear(const Hypotheses& hyp, size_t frame, int laser, const Eigen::Vector3d& point,
               double radius) const {
    const auto begin = entries_.begin() + first_[frame * kMaxLasers + laser];
    const auto end = entries_.begin() + first_[frame * kMaxLasers + laser + 1];
    if (begin == end) return false;
    const double r2 = radius * radius;
    const int x0 = CellIndex(point.x() - radius), x1 = CellIndex(point.x() + radius);
    const int y0 = CellIndex(point.y() - radius), y1 = CellIndex(point.y() + radius);
    for (int x = x0; x <= x1; ++x) {
      // Cells of one x are consecutive in y.
      const uint32_t lo = Pack(x, y0), hi = Pack(x, y1);
      for (auto it = std::lower_bound(begin, end, lo,
                                      [](const Entry&e, uint32_t c) { return e.cell < c; });
           it != end && it->cell <= hi; ++it) {
        if ((hyp[it->hyp].point - point).squaredNorm() <= r2) return true;
      }
    }
    return false;
  }

 private:
  static constexpr double kCellMm = 8.0;
  struct Entry {
    uint32_t cell;
    uint32_t hyp;
  };
  static int CellIndex(double mm) { return static_cast<int>(std::floor(mm / kCellMm)) + 32768; }
  static uint32_t Pack(int x, int y) {
    return static_cast<uint32_t>(std::clamp(x, 0, 65535)) << 16 |
           static_cast<uint32_t>(std::clamp(y, 0, 65535));
  }
  static uint32_t Cell(double x, double y) { return Pack(CellIndex(x), CellIndex(y)); }
  std::vector<uint32_t> first_;  // per (frame, laser), and one past the end
  std::vector<Entry> entries_;
};

}  // namespace

void ConfirmByStereo(const ScanArchive& archive, const PeakTable& table,
                     const std::vector<std::array<Plane, kMaxLasers>>& planes, double max_mm,
                     int threads, Hypotheses* hyp) {
  const size_t frames = table.frame_first.size() - 1;
  // Per camera, its frames in time order and its frame period.
  size_t cameras = 0;
  for (size_t f = 0; f < frames; ++f)
    if (table.frame_first[f + 1] > table.frame_first[f])
      cameras = std::max<size_t>(cameras, archive.frames[f].camera + 1);
  if (cameras < 2) return;
  std::vector<std::vector<std::pair<int64_t, uint32_t>>> by_time(cameras);
  for (size_t f = 0; f < frames; ++f)
    if (table.frame_first[f + 1] > table.frame_first[f])
      by_time[archive.frames[f].camera].emplace_back(archive.frames[f].timestamp_ns, f);
  std::vector<int64_t> period(cameras, 0);
  for (size_t c = 0; c < cameras; ++c) {
    auto& list = by_time[c];
    std::sort(list.begin(), list.end());
    std::vector<int64_t> steps;
    for (size_t i = 1; i < list.size(); ++i) steps.push_back(list[i].first - list[i - 1].first);
    if (!steps.empty()) {
      std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
      period[c] = steps[steps.size() / 2];
    }
  }
  const HypothesisIndex index(table, *hyp);
  // Each frame marks only its own hypotheses and reads the others' points, which stay.
  ParallelFor(frames, threads, [&](size_t frames_begin, size_t frames_end) {
    std::vector<uint32_t> partners;
    for (size_t f = frames_begin; f < frames_end; ++f) {
      if (table.frame_first[f + 1] == table.frame_first[f]) continue;
      const FrameRecord& frame = archive.frames[f];
      partners.clear();
      for (size_t c = 0; c < cameras; ++c) {
        if (c == frame.camera || by_time[c].empty()) continue;
        const auto& list = by_time[c];
        const auto it = std::lower_bound(list.begin(), list.end(),
                                         std::make_pair(frame.timestamp_ns, uint32_t{0}));
        // The frames either side within three quarters of a period.
        for (auto near : {it, it == list.begin() ? list.end() : it - 1}) {
          if (near == list.end()) continue;
          if (4 * std::abs(near->first - frame.timestamp_ns) <= 3 * period[c])
            partners.push_back(near->second);
        }
      }
      if (partners.empty()) continue;
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        if (p.hypotheses < 2) continue;
        for (int h = 0; h < p.hypotheses; ++h) {
          Hypothesis& x = (*hyp)[p.first_hypothesis + h];
          const int laser = x.key % kMaxLasers;
          for (uint32_t g : partners) {
            const Plane& plane = planes[g][laser];
            if (std::abs(plane.normal.z()) < 0.5) continue;
            // Where the other frame's plane is above this point: the stripe has moved by that.
            const double z =
                -(plane.normal.x() * x.point.x() + plane.normal.y() * x.point.y() + plane.offset) /
                plane.normal.z();
            const Eigen::Vector3d moved(x.point.x(), x.point.y(), z);
            if (index.AnyNear(*hyp, g, laser, moved, max_mm + std::abs(z - x.point.z()))) {
              x.confirmed = true;
              break;
            }
          }
        }
      }
    }
  });
}

void DecideByStereo(const Hypotheses& hyp, int threads, std::vector<PeakState>* peaks) {
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.rule != Rule::kNone || p.hypotheses < 2) continue;
      const uint32_t allowed = SequenceAllows(&hyp[p.first_hypothesis], p.hypotheses);
      int confirmed = 0, last_confirmed = -1;
      for (int h = 0; h < p.hypotheses; ++h) {
        if (!(allowed >> h & 1u)) continue;
        if (hyp[p.first_hypothesis + h].confirmed) {
          ++confirmed;
          last_confirmed = h;
        }
      }
      if (confirmed != 1) continue;
      p.chosen = static_cast<int16_t>(last_confirmed);
      p.rule = Rule::kStereo;
    }
  });
}

}  // namespace mirrorscan::reconstruction

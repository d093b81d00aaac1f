#include "host/reconstruction/rules/label_vote.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/voxel_box.h"

namespace mirrorscan::reconstruction {

namespace {

// Neighbours of one hypothesis closer than this in 3D belong to one surface.
constexpr double kLinkColumnMm = 6.0;
constexpr double kLinkFrameMm = 25.0;

// Per voxel (20 mm), the (view, laser) keys of the peaks decided without the vote near it.
// A mirror stripe that no rule decided can be joined to a real surface in front of the
// mirror by a chain of its phantom hypotheses (its direct ray meeting another laser's plane
// in the air beside an arm); the vote would carry that surface's key along the whole chain,
// so in a mirror's region it gives the direct view only to points near peaks decided so.
constexpr double kKeyOccupancyVoxelMm = 20.0;
static_assert(kKeys <= 16, "one bit per key in a uint16_t");

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t Find(uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void Join(uint32_t a, uint32_t b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

// A common hypothesis of two peaks whose points are within max_mm.
bool Consistent(const Hypotheses& hyp, const PeakState& a, const PeakState& b, double max_mm) {
  const double max2 = max_mm * max_mm;
  for (int i = 0; i < a.hypotheses; ++i) {
    const Hypothesis& ha = hyp[a.first_hypothesis + i];
    for (int j = 0; j < b.hypotheses; ++j) {
      const Hypothesis& hb = hyp[b.first_hypothesis + j];
      if (ha.key == hb.key && (ha.point - hb.point).squaredNorm() < max2) return true;
    }
  }
  return false;
}

int FindHypothesis(const Hypotheses& hyp, const PeakState& p, int key) {
  for (int i = 0; i < p.hypotheses; ++i) {
    if (hyp[p.first_hypothesis + i].key == key) return i;
  }
  return -1;
}

// Joins peaks that are neighbours in (column, frame) and agree on some hypothesis.
void LinkNeighbours(const PeakTable& table, const Hypotheses& hyp,
                    const ReconstructOptions& options, UnionFind* labels) {
  const size_t frames = table.frame_first.size() - 1;
  // Two neighbours decided with different keys are two surfaces that touch in the image (a
  // mirror's stripe beside the subject's stripe of another laser in front of the mirror):
  // joined, the larger one's vote would take the other's peaks.
  auto join = [&](uint32_t a, uint32_t b) {
    const PeakState& pa = table.peaks[a];
    const PeakState& pb = table.peaks[b];
    if (pa.chosen >= 0 && pb.chosen >= 0 &&
        hyp[pa.first_hypothesis + pa.chosen].key != hyp[pb.first_hypothesis + pb.chosen].key)
      return;
    labels->Join(a, b);
  };
  for (size_t f = 0; f < frames; ++f) {
    const uint32_t begin = table.frame_first[f], end = table.frame_first[f + 1];
    // Column neighbours: the run at u + 1 starts after the run at u.
    uint32_t next_col = begin;
    for (uint32_t i = begin; i < end; ++i) {
      const PeakState& p = table.peaks[i];
      if (p.hypotheses == 0) continue;
      while (next_col < end && table.peaks[next_col].u <= p.u) ++next_col;
      for (uint32_t j = next_col; j < end && table.peaks[j].u == p.u + 1; ++j) {
        const PeakState& q = table.peaks[j];
        if (q.hypotheses == 0 || std::abs(q.v - p.v) > options.label_max_row_step_px) continue;
        if (Consistent(hyp, p, q, kLinkColumnMm)) join(i, j);
      }
    }
    const int32_t g = table.next_frame[f];
    if (g < 0) continue;
    for (uint32_t i = begin; i < end;) {
      const uint16_t u = table.peaks[i].u;
      uint32_t run_end = i;
      while (run_end < end && table.peaks[run_end].u == u) ++run_end;
      const auto [lo, hi] = table.Column(static_cast<uint32_t>(g), u);
      for (uint32_t a = i; a < run_end; ++a) {
        const PeakState& p = table.peaks[a];
        if (p.hypotheses == 0) continue;
        for (uint32_t b = lo; b < hi; ++b) {
          const PeakState& q = table.peaks[b];
          if (q.hypotheses == 0 || std::abs(q.v - p.v) > options.label_max_frame_step_px) continue;
          if (Consistent(hyp, p, q, kLinkFrameMm)) join(a, b);
        }
      }
      i = run_end;
    }
  }
}

}  // namespace

void DecideByLabelVote(const Hypotheses& hyp, const ReconstructOptions& options, int threads,
                       PeakTable* table, ReconstructSummary* summary) {
  const size_t n = table->peaks.size();
  UnionFind union_find(n);
  UnionFind* labels = &union_find;
  LinkNeighbours(*table, hyp, options, labels);
  const BoundingCylinder& cylinder = options.cylinder;
  NeighbourhoodBits<uint16_t> decided(cylinder, kKeyOccupancyVoxelMm);
  for (const PeakState& p : table->peaks) {
    if (p.chosen < 0) continue;
    const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
    decided.Add(h.point, static_cast<uint16_t>(1u << h.key));
  }
  decided.Spread(threads);
  std::vector<int32_t> label_of_root(n, -1);
  std::vector<std::array<uint32_t, kKeys>> votes;
  std::vector<int32_t> label(n, -1);
  for (uint32_t i = 0; i < n; ++i) {
    const PeakState& p = table->peaks[i];
    if (p.hypotheses == 0 || p.panel) continue;
    const uint32_t root = labels->Find(i);
    if (label_of_root[root] < 0) {
      label_of_root[root] = static_cast<int32_t>(votes.size());
      votes.push_back({});
    }
    label[i] = label_of_root[root];
    if (p.chosen >= 0) ++votes[label[i]][hyp[p.first_hypothesis + p.chosen].key];
  }
  std::vector<int> winner(votes.size(), -1);
  for (size_t l = 0; l < votes.size(); ++l) {
    const auto best = std::max_element(votes[l].begin(), votes[l].end());
    if (*best > 0) winner[l] = static_cast<int>(best - votes[l].begin());
  }
  // Each peak decided on its own from its label's winner, chunk by chunk.
  struct Counts {
    size_t ambiguous = 0, conflict = 0, unsupported = 0;
  };
  std::vector<Counts> counts(ChunkCount(n, threads));
  ForEachChunk(n, threads, [&](size_t chunk, size_t begin, size_t end) {
    Counts& count = counts[chunk];
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = table->peaks[i];
      if (label[i] < 0) continue;
      const int key = winner[label[i]];
      if (key < 0) {
        ++count.ambiguous;
        p.chosen = -1;
        continue;
      }
      const int h = FindHypothesis(hyp, p, key);
      if (h < 0 || (p.chosen >= 0 && p.chosen != h)) {
        ++count.conflict;
        p.chosen = -1;
        p.rule = Rule::kNone;
        continue;
      }
      if (p.chosen < 0) {
        // Only the direct view in a mirror's region is at risk: there the direct ray's other
        // lasers' points lie in the air beside whatever stands in front of the mirror.
        if (p.region != 0 && key / kMaxLasers == static_cast<int>(PointView::kCenter) &&
            !(decided.At(hyp[p.first_hypothesis + h].point) >> key & 1u)) {
          ++count.unsupported;
          continue;
        }
        p.chosen = static_cast<int16_t>(h);
        p.rule = Rule::kLabelVote;
      }
    }
  });
  for (const Counts& count : counts) {
    summary->dropped_ambiguous += count.ambiguous;
    summary->dropped_conflict += count.conflict;
    summary->dropped_unsupported += count.unsupported;
  }
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/rules/label_vote.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/laser_sequence.h"
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

// A label joins every pair of neighbours that agree; a surface (part of a label) refuses to
// join two parts to which peaks decided alone (stereo, the cylinder) gave different keys:
// two surfaces that touch in the image (an arm's silhouette running along a mirror's stripe
// for 20 frames), joined through peaks no rule decided. In cabinet G the lower camera's
// labels held two mirrors' stripes and the arm's at once, and the majority dropped 16,000
// right peaks of the others (docs/reconstruction.md, stage 4).
constexpr uint16_t kNoKey = 0xffff;
// A surface whose key is not its label's majority keeps it only with this many decided
// peaks and this share of the label's: what a rule decided wrong in a stretch of another key
// was 1-6 peaks on the people measured in cabinet G, and 77 and 100 (1.2 % of their label)
// where the mannequin's two cameras confirmed each other's phantoms of its hips in the
// mirrors (CylinderRule.HandsBeyondTheCoreComeOutWithTheirLaserAndView); the right surfaces
// were 16-34 % of their labels (thousands of peaks), and 1-2 % (241, 284 peaks, dropped).
constexpr uint32_t kMinOwnSurfacePeaks = 20;
constexpr double kMinOwnSurfaceShare = 0.05;

struct UnionFind {
  std::vector<uint32_t> parent;
  std::vector<uint16_t> key;  // surfaces: per root, the key its peaks decided alone have
  explicit UnionFind(size_t n, bool surfaces = false) : parent(n), key(surfaces ? n : 0, kNoKey) {
    std::iota(parent.begin(), parent.end(), 0u);
  }
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
    if (a == b) return;
    if (!key.empty()) {
      if (key[a] != kNoKey && key[b] != kNoKey && key[a] != key[b]) return;
      key[std::min(a, b)] = key[a] != kNoKey ? key[a] : key[b];
    }
    parent[std::max(a, b)] = std::min(a, b);
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

// Joins peaks that are neighbours in (column, frame) and agree on some hypothesis, into
// labels and into surfaces.
void LinkNeighbours(const PeakTable& table, const Hypotheses& hyp,
                    const ReconstructOptions& options, UnionFind* labels, UnionFind* surfaces) {
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
    surfaces->Join(a, b);
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
  UnionFind labels(n);
  UnionFind surfaces(n, /*surfaces=*/true);
  for (size_t i = 0; i < n; ++i) {
    const PeakState& p = table->peaks[i];
    if (p.chosen >= 0 && (p.rule == Rule::kStereo || p.rule == Rule::kCylinder))
      surfaces.key[i] = hyp[p.first_hypothesis + p.chosen].key;
  }
  LinkNeighbours(*table, hyp, options, &labels, &surfaces);
  const BoundingCylinder& cylinder = options.cylinder;
  NeighbourhoodBits<uint16_t> decided(cylinder, kKeyOccupancyVoxelMm);
  for (const PeakState& p : table->peaks) {
    if (p.chosen < 0) continue;
    const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
    decided.Add(h.point, static_cast<uint16_t>(1u << h.key));
  }
  decided.Spread(threads);
  // Votes per label and per surface (indices into `votes`).
  std::vector<int32_t> index_of_root(2 * n, -1);
  std::vector<std::array<uint32_t, kKeys>> votes;
  std::vector<int32_t> label(n, -1), surface(n, -1);
  const auto index = [&](size_t root) {
    if (index_of_root[root] < 0) {
      index_of_root[root] = static_cast<int32_t>(votes.size());
      votes.push_back({});
    }
    return index_of_root[root];
  };
  for (uint32_t i = 0; i < n; ++i) {
    const PeakState& p = table->peaks[i];
    if (p.hypotheses == 0 || p.panel) continue;
    label[i] = index(labels.Find(i));
    surface[i] = index(n + surfaces.Find(i));
    if (p.chosen < 0) continue;
    const int key = hyp[p.first_hypothesis + p.chosen].key;
    ++votes[label[i]][key];
    ++votes[surface[i]][key];
  }
  std::vector<int> winner(votes.size(), -1);
  std::vector<uint32_t> decided_count(votes.size(), 0);
  for (size_t l = 0; l < votes.size(); ++l) {
    const auto best = std::max_element(votes[l].begin(), votes[l].end());
    if (*best > 0) winner[l] = static_cast<int>(best - votes[l].begin());
    for (uint32_t c : votes[l]) decided_count[l] += c;
  }
  // A surface keeps its own key against its label's majority only when it is large enough to
  // be a surface of its own.
  const auto key_of = [&](size_t i) {
    const int own = winner[surface[i]];
    const uint32_t own_count = decided_count[surface[i]];
    if (own == winner[label[i]] || (own_count >= kMinOwnSurfacePeaks &&
                                    own_count >= kMinOwnSurfaceShare * decided_count[label[i]]))
      return own;
    return winner[label[i]];
  };
  // Each peak decided on its own from its surface's or label's key, chunk by chunk.
  struct Counts {
    size_t ambiguous = 0, conflict = 0, unsupported = 0;
  };
  std::vector<Counts> counts(ChunkCount(n, threads));
  ForEachChunk(n, threads, [&](size_t chunk, size_t begin, size_t end) {
    Counts& count = counts[chunk];
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = table->peaks[i];
      if (label[i] < 0) continue;
      const int key = key_of(i);
      // A peak not decided alone that could be either its surface's or its label's is where
      // the two touch: it joined the surface through a hypothesis that the label's majority
      // says is the phantom (the mannequin's chest, seen directly, joined to the right
      // mirror's stripe through its ray's point in the mirror: 848 wrong peaks undecided,
      // 435 that the volume or the column count took for the mirror's).
      const int label_key = winner[label[i]];
      const bool alone = p.rule == Rule::kStereo || p.rule == Rule::kCylinder;
      if (key < 0 || (!alone && key != label_key && label_key >= 0 &&
                      FindHypothesis(hyp, p, label_key) >= 0)) {
        ++count.ambiguous;
        p.chosen = -1;
        continue;
      }
      const int h = FindHypothesis(hyp, p, key);
      // Another camera confirmed this peak's own choice, and the laser sequence at its pixel
      // says no to the label's key (or the label's key is none of its hypotheses): the stereo
      // choice stands. The label had joined the feet in the mirrors at the sweep's start
      // (laser 0, at the floor) to the shins seen directly (laser 2): most of f04's 7,942
      // conflicts (two cameras, the factory calibration) and 8,022 (three) were right stereo
      // decisions undone.
      if (p.rule == Rule::kStereo && p.chosen >= 0 && p.chosen != h &&
          (h < 0 || SequenceRefutes(&hyp[p.first_hypothesis], p.hypotheses, h)))
        continue;
      if (h < 0 || (p.chosen >= 0 && p.chosen != h)) {
        ++count.conflict;
        p.chosen = -1;
        p.rule = Rule::kNone;
        continue;
      }
      if (p.chosen < 0) {
        // Only the direct view in a mirror's region is at risk, and only where the peak can
        // be the mirror's: there the direct ray's other lasers' points lie in the air beside
        // whatever stands in front of the mirror. A ray whose mirror view meets no laser in
        // the cylinder is no mirror's stripe (in cabinet G the whole direct view lies in the
        // mirrors' regions, and 17,474 right peaks of m05's chest and shoulders were dropped).
        const Hypothesis* first = &hyp[p.first_hypothesis];
        const bool mirror_hyp = std::any_of(first, first + p.hypotheses, [](const Hypothesis& x) {
          return !x.Background() && x.key / kMaxLasers != static_cast<int>(PointView::kCenter);
        });
        if (p.region != 0 && mirror_hyp &&
            key / kMaxLasers == static_cast<int>(PointView::kCenter) &&
            !(decided.At(hyp[p.first_hypothesis + h].point) >> key & 1u)) {
          ++count.unsupported;
          continue;
        }
        // A label carries its key along a stripe that another surface's stripe joins; the
        // laser sequence at the pixel can still say no (f11's and m08's heels in the
        // mirrors at the sweep's start, laser 0, taken for laser 1 in the air 200 mm above).
        if (SequenceRefutes(first, p.hypotheses, h)) {
          ++count.conflict;
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

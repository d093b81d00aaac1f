#include "host/reconstruction/rules/cylinder.h"

#include <algorithm>
#include <cstdlib>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/laser_sequence.h"

namespace mirrorscan::reconstruction {

void DecideByOneHypothesis(int threads, std::vector<PeakState>* peaks) {
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.hypotheses != 1) continue;
      p.chosen = 0;
      p.rule = Rule::kCylinder;
    }
  });
}

void DecideByCore(const Hypotheses& hyp, const BoundingCylinder& cylinder, int threads,
                  std::vector<PeakState>* peaks) {
  const auto is_direct = [](const Hypothesis& x) {
    return x.key / kMaxLasers == static_cast<int>(PointView::kCenter);
  };
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.rule != Rule::kNone || p.hypotheses < 2) continue;
      const Hypothesis* first = &hyp[p.first_hypothesis];
      const bool any_confirmed =
          std::any_of(first, first + p.hypotheses, [](const Hypothesis& x) { return x.confirmed; });
      const uint32_t allowed = SequenceAllows(first, p.hypotheses);
      int in_core = 0, last_in_core = -1;
      for (int h = 0; h < p.hypotheses; ++h) {
        if ((!any_confirmed || first[h].confirmed) && (allowed >> h & 1u) &&
            (first[h].Background() || cylinder.CoreContains(first[h].point))) {
          ++in_core;
          last_in_core = h;
        }
      }
      if (in_core != 1) continue;
      // The direct ray in a mirror's region meets the other lasers' planes in the air beside
      // whatever stands in front of the mirror, often inside the core: no proof while the
      // mirror's view has a hypothesis further out (a hand seen in the mirror).
      // And the other way round: the mirror's view meets a laser's plane inside the core, in
      // the air in front of the legs, while the truth is a hand in front of the mirror, outside
      // the core.
      if (p.region != 0 && std::any_of(first, first + p.hypotheses, [&](const Hypothesis& x) {
            return !x.Background() && is_direct(x) != is_direct(first[last_in_core]);
          }))
        continue;
      p.chosen = static_cast<int16_t>(last_in_core);
      p.rule = Rule::kCylinder;
    }
  });
}

}  // namespace mirrorscan::reconstruction

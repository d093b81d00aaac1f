#include "host/reconstruction/laser_sequence.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// At every pixel the other lasers light the truth's point at their moments: the sequence
// allows the truth's hypothesis, and refuses most hypotheses of the same view with another
// laser (a point a spacing above or below the surface), on a person in cabinet G (206,884 of
// 208,156 truth's allowed, 124,814 of 213,053 shifted refused: on a stretch of 100 frames
// many of the other lasers' moments lie outside it, and then the sequence says nothing).
TEST(LaserSequence, AllowsTheTruthsLaserAndRefusesAShiftedOne) {
  const Sweep& sweep = PersonInCabinetG();
  const RuleBench bench(sweep, CabinetGOptions());
  size_t peaks = 0, truth_allowed = 0, shifted = 0, shifted_refused = 0;
  for (const PeakState& p : bench.t.table.peaks) {
    if (p.hypotheses < 2) continue;
    const FrameRecord& frame = sweep.archive.frames[p.frame];
    const TruthPeak* truth = Match(sweep, frame.camera, static_cast<int>(frame.sequence), p.u, p.v);
    if (!truth) continue;
    const Hypothesis* first = &bench.t.hyp[p.first_hypothesis];
    const uint32_t allowed = SequenceAllows(first, p.hypotheses);
    for (int h = 0; h < p.hypotheses; ++h) {
      if (first[h].Background() || first[h].key / kMaxLasers != static_cast<int>(truth->view))
        continue;
      if (first[h].key % kMaxLasers == truth->laser) {
        ++peaks;
        if (allowed >> h & 1u) ++truth_allowed;
      } else {
        ++shifted;
        if (!(allowed >> h & 1u)) ++shifted_refused;
      }
    }
  }
  std::printf("truth's hypothesis allowed at %zu of %zu peaks; %zu of %zu shifted refused\n",
              truth_allowed, peaks, shifted_refused, shifted);
  EXPECT_GT(peaks, 20000u);
  EXPECT_GE(truth_allowed, peaks * 0.99);
  EXPECT_GE(shifted_refused, shifted * 0.5);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

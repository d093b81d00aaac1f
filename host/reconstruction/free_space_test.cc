#include "host/reconstruction/free_space.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// Points that the vote gave a wrong laser or view lie where other lasers at the same pixel,
// or the other camera and views, see another surface or look through.
TEST(FreeSpace, PointsThatOtherLasersAndViewsSeeThroughAreDropped) {
  const Sweep& sweep = MannequinSweep();
  ReconstructOptions without;
  without.free_space_check = false;
  const Reconstruction before = Reconstruct(sweep.archive, sweep.calibration, without);
  const Reconstruction after = Reconstruct(sweep.archive, sweep.calibration);
  const Score b = ScoreAgainstTruth(sweep, before.cloud);
  const Score a = ScoreAgainstTruth(sweep, after.cloud);
  std::printf("without the check: %zu points, %zu wrong, %zu right; with: %zu, %zu, %zu\n%s",
              b.points, b.wrong, b.found_right, a.points, a.wrong, a.found_right,
              SummaryText(after.summary).c_str());
  EXPECT_EQ(before.summary.dropped_seen_through, 0u);
  EXPECT_GT(after.summary.dropped_seen_through, 0u);
  EXPECT_LT(a.wrong, b.wrong);
  EXPECT_LE(a.wrong, 10u);
  EXPECT_GE(a.found_right, b.found_right * 0.995);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

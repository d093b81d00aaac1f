#include "host/reconstruction/filters.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

TEST(Filters, FiltersAreSwitchable) {
  const Sweep& sweep = CuboidSweep();
  ReconstructOptions raw;
  raw.smooth_3x3 = false;
  raw.remove_outliers = false;
  const Reconstruction unfiltered = Reconstruct(sweep.archive, sweep.calibration, raw);
  const Reconstruction filtered = Reconstruct(sweep.archive, sweep.calibration);
  EXPECT_EQ(unfiltered.summary.dropped_outlier, 0u);
  // Averaging 3×3 neighbours cuts the noise on the faces.
  EXPECT_LT(ScoreAgainstTruth(sweep, filtered.cloud).rms_mm,
            0.8 * ScoreAgainstTruth(sweep, unfiltered.cloud).rms_mm);
  // Every camera's points by default; asked, merging prefers the camera that meets the
  // planes squarer where both see a place.
  EXPECT_EQ(filtered.summary.dropped_other_camera, 0u);
  ReconstructOptions prefer;
  prefer.prefer_camera_ratio = 1.5;
  EXPECT_GT(Reconstruct(sweep.archive, sweep.calibration, prefer).summary.dropped_other_camera, 0u);
  ReconstructOptions ends;
  ends.drop_stripe_ends = true;
  const Reconstruction trimmed = Reconstruct(sweep.archive, sweep.calibration, ends);
  EXPECT_GT(trimmed.summary.dropped_stripe_end, 0u);
  EXPECT_LT(trimmed.summary.points, filtered.summary.points);
  ReconstructOptions confident;
  confident.min_confidence = 0.15;
  const Reconstruction sure = Reconstruct(sweep.archive, sweep.calibration, confident);
  EXPECT_EQ(filtered.summary.dropped_low_confidence, 0u);
  EXPECT_GT(sure.summary.dropped_low_confidence, 0u);
  // Every point left is at least 0.15, so the surface check dropped none of the weak ones
  // (what it dropped are the outlier test's points, counted as outliers).
  EXPECT_EQ(sure.summary.dropped_off_surface, 0u);
  const auto judged = [](const ReconstructSummary& s) {
    return s.points + s.dropped_low_confidence + s.dropped_off_surface +
           s.dropped_flat_off_surface + s.dropped_outlier + s.dropped_outside;
  };
  EXPECT_EQ(judged(sure.summary), judged(filtered.summary));
  for (const CloudPoint& p : sure.cloud.points) ASSERT_GE(p.confidence, 0.15f);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

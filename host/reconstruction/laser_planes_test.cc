#include "host/reconstruction/laser_planes.h"

#include <string>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

TEST(LaserPlanes, SlideReadbackStandsInWhenThePanelsCannotBeUsed) {
  const Sweep& sweep = CuboidSweep();
  // Without mirror corners there are no panels to measure on.
  Calibration calibration = sweep.calibration;
  for (CalibrationMirror& m : calibration.mirrors) m.corners_mm.clear();
  ReconstructOptions options;
  options.allow_calibration_mismatch = true;  // the geometry changed, so the hash did
  const Reconstruction r = Reconstruct(sweep.archive, calibration, options);
  EXPECT_EQ(r.summary.laser_height.source, "readback");
  EXPECT_NE(r.summary.laser_height.reason.find("corners"), std::string::npos)
      << r.summary.laser_height.reason;
  const Score score = ScoreAgainstTruth(sweep, r.cloud);
  EXPECT_LE(score.wrong, score.points * 0.001);
  EXPECT_LT(score.rms_mm, 0.25);  // the cuboid's saturated front (Reconstruct.Cuboid...)

  ReconstructOptions readback;
  readback.laser_height_from_panels = false;
  const Reconstruction by_option = Reconstruct(sweep.archive, sweep.calibration, readback);
  EXPECT_EQ(by_option.summary.laser_height.source, "readback");
  EXPECT_LT(ScoreAgainstTruth(sweep, by_option.cloud).rms_mm, 0.25);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

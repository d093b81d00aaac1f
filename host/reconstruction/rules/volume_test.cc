#include "host/reconstruction/rules/volume.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/rules/cylinder.h"
#include "host/reconstruction/rules/stereo.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// The upper camera sees the torso's back in the mirrors where no peak was decided alone,
// and the same ray, on through the torso, meets the next laser's plane down beside the
// forearm, inside the carved volume; and in a mirror's region an arm in front of the glass
// makes a column hold as many peaks as lasers without being the lasers. Neither may take
// the back's stripes from it.
TEST(VolumeRule, TheTorsosBackInTheMirrorsKeepsItsLaser) {
  const Sweep& sweep = MannequinSweep();
  const Reconstruction r = Reconstruct(sweep.archive, sweep.calibration);
  const Score score = ScoreAgainstTruth(sweep, r.cloud);
  // The back: the upper camera's mirror views, behind the torso's axis.
  const auto on_back = [](const TruthPeak& t) {
    return t.camera == 0 && t.view != virtual_cabinet::View::kCenter && t.point_in_world.y() > 0 &&
           t.point_in_world.head<2>().norm() < 250;
  };
  size_t back = 0, back_found = 0;
  for (const auto& [key, column] : sweep.truth)
    for (const TruthPeak& t : column) back += on_back(t);
  for (const CloudPoint& p : r.cloud.points) {
    const TruthPeak* t = Match(sweep, p);
    if (t && on_back(*t) && t->laser == p.laser &&
        static_cast<int>(t->view) == static_cast<int>(p.view))
      ++back_found;
  }
  std::printf(
      "%zu points, %zu wrong, %zu of %zu truth (%zu reconstructable); the back: %zu of "
      "%zu\n%s",
      score.points, score.wrong, score.found_right, sweep.truth_points, sweep.truth_reconstructable,
      back_found, back, SummaryText(r.summary).c_str());
  EXPECT_LE(score.wrong, score.points * 0.0005);
  // 17,637 of the back's 24,009 truth points and 99,001 of the 101,365 reconstructable. Planted:
  // the volume not walking the mirrors' rays 17,248 and 98,612; the column count checked
  // neither against its decided peaks nor for one view 17,488 and 98,906; the outlier test
  // dropping what it flags
  // without the surface's word 17,574 and 98,724.
  EXPECT_GE(back_found, back * 0.732);
  EXPECT_GE(score.found_right, sweep.truth_reconstructable * 0.976);
}

// The one hypothesis in the carved volume that the ray reaches without passing a seen
// surface is the truth's laser and view: on the cuboid all but 6 of 6,872 (with the fourth
// emitter behind the subject; 0 with three): the lower camera's top rows (v < 50) seeing
// the tripod's pole at z 1000 in the left mirror, taken for the next laser on the direct
// ray in front of the glass, 400 mm out (the final cloud keeps 2 wrong of 57,836,
// Reconstruct.CuboidThroughTheTrueCalibrationMatchesTheTruth); on the mannequin's
// stretch 1,259 of 14,876 are not with the 850 mm cylinder (784 of 11,663 with 650 mm; 588
// of 16,108 in the mannequin's cabinet), all in a mirror's region, and the stages after it
// drop them (TheTorsosBackInTheMirrorsKeepsItsLaser, above).
TEST(VolumeRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kVolume);
  EXPECT_GT(cuboid.matched, 6000u);
  EXPECT_LE(cuboid.wrong, 6u);
  EXPECT_GT(mannequin.matched, 11000u);
  EXPECT_LE(mannequin.wrong, mannequin.matched / 11);
  EXPECT_EQ(mannequin.wrong_in_centre, 0u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

#include "host/reconstruction/rules/stereo.h"

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// The one hypothesis another camera confirms is the truth's laser and view: on the cuboid
// every time; on the mannequin's stretch 215 of 43,355 are not, all but 2 in a mirror's
// region, and the stages after it drop them (TheTorsosBackInTheMirrorsKeepsItsLaser).
TEST(StereoRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kStereo);
  EXPECT_GT(cuboid.matched, 10000u);
  EXPECT_EQ(cuboid.wrong, 0u);
  EXPECT_GT(mannequin.matched, 35000u);
  EXPECT_LE(mannequin.wrong, mannequin.matched * 3 / 400);
  EXPECT_LE(mannequin.wrong_in_centre, 10u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

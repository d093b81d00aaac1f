#include "host/reconstruction/rules/stereo.h"

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// The one hypothesis another camera confirms is the truth's laser and view, but for a few
// in a mirror's region, which the stages after it drop (TheTorsosBackInTheMirrorsKeepsItsLaser):
// in the cabinet for people 26 of the cuboid's 15,761 and 64 of the mannequin's 58,832.
TEST(StereoRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kStereo);
  EXPECT_GT(cuboid.matched, 10000u);
  EXPECT_LE(cuboid.wrong, cuboid.matched / 400);
  EXPECT_EQ(cuboid.wrong_in_centre, 0u);
  EXPECT_GT(mannequin.matched, 35000u);
  EXPECT_LE(mannequin.wrong, mannequin.matched * 3 / 400);
  EXPECT_LE(mannequin.wrong_in_centre, 10u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

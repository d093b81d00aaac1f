#include "host/reconstruction/rules/label_vote.h"

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// What a label's majority gives its undecided peaks is the truth's laser and view, on the
// cuboid and on the mannequin's stretch, where the rules before it erred in the mirrors'
// regions (their wrong decisions are not carried along); in the cabinet for people 6 of the
// mannequin's 3,665, in a mirror's region, which the stages after it drop.
TEST(LabelVoteRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kLabelVote);
  EXPECT_GT(cuboid.matched, 5000u);
  EXPECT_EQ(cuboid.wrong, 0u);
  EXPECT_GT(mannequin.matched, 3000u);
  EXPECT_LE(mannequin.wrong, 10u);
  EXPECT_EQ(mannequin.wrong_in_centre, 0u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

#include "host/reconstruction/rules/label_vote.h"

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// What a label's majority gives its undecided peaks is the truth's laser and view, on the
// cuboid and on the mannequin's stretch, where the rules before it erred in the mirrors'
// regions (their wrong decisions are not carried along).
TEST(LabelVoteRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kLabelVote);
  EXPECT_GT(cuboid.matched, 5000u);
  EXPECT_EQ(cuboid.wrong, 0u);
  EXPECT_GT(mannequin.matched, 10000u);
  EXPECT_EQ(mannequin.wrong, 0u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

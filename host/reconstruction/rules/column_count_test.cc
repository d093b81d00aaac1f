#include "host/reconstruction/rules/column_count.h"

#include <gtest/gtest.h>

#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

// Where a column of a view region holds as many peaks as lasers, top to bottom, what the
// count decides is the truth's laser and view: on the cuboid every time, and in the
// mannequin's centre region. In a mirror's region an arm in front of the glass adds its
// stripe where one of the mirror's is missing, consistently enough that the column's checks
// pass (the mannequin's stretch, its arms in front of the mirrors: 2,246 of 5,874 wrong);
// the arm's stripe runs on into the centre region, and the stages after it drop them
// (TheTorsosBackInTheMirrorsKeepsItsLaser).
TEST(ColumnCountRule, DecidesTheTruthsLaserAndView) {
  const auto [cuboid, mannequin] = ScoreOnBothSweeps(Rule::kColumnCount);
  EXPECT_GT(cuboid.matched, 800u);
  EXPECT_EQ(cuboid.wrong, 0u);
  EXPECT_GT(mannequin.matched, 1800u);  // 1,899 with the emitter behind the subject
  EXPECT_EQ(mannequin.wrong_in_centre, 0u);
  // Without the column's checks (a row decided already with another laser, rows of more than
  // one view) 2,522 wrong.
  EXPECT_LE(mannequin.wrong, 2400u);
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps

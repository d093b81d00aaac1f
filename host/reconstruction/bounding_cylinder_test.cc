#include "host/reconstruction/bounding_cylinder.h"

#include <gtest/gtest.h>

namespace mirrorscan::reconstruction {
namespace {

TEST(BoundingCylinder, HoldsTheSubjectItsCoreAndTheFloorBelow) {
  BoundingCylinder c;
  c.center_mm = {10, -20};
  c.radius_mm = 300;
  c.core_radius_mm = 200;
  c.bottom_mm = 20;
  c.top_mm = 1900;
  EXPECT_TRUE(c.Contains({10, 279, 1000}));
  EXPECT_FALSE(c.Contains({10, 281, 1000}));
  EXPECT_FALSE(c.Contains({10, 0, 1901}));
  EXPECT_FALSE(c.Contains({10, 0, 19}));
  EXPECT_TRUE(c.CoreContains({10, 179, 1000}));
  EXPECT_FALSE(c.CoreContains({10, 181, 1000}));
  // The floor: below the bottom, down to a little under z 0, as wide as the cylinder.
  EXPECT_TRUE(c.OnFloor({10, 100, 5}));
  EXPECT_TRUE(c.OnFloor({10, 100, -15}));
  EXPECT_FALSE(c.OnFloor({10, 100, -25}));
  EXPECT_FALSE(c.OnFloor({10, 100, 30}));
  EXPECT_FALSE(c.OnFloor({10, 281, 5}));
  EXPECT_FALSE(c.Contains({10, 100, 5}));
  // The core is never wider than the cylinder.
  c.core_radius_mm = 400;
  EXPECT_FALSE(c.CoreContains({10, 281, 1000}));
}

}  // namespace
}  // namespace mirrorscan::reconstruction

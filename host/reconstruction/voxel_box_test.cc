#include "host/reconstruction/voxel_box.h"

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace mirrorscan::reconstruction {
namespace {

// After Spread(), a voxel's bits are the OR of the points in it and its 26 neighbours, as a
// direct search over the points says; points up to a voxel outside the box still reach in.
TEST(VoxelBox, NeighbourhoodBitsAreTheOrOfTheTwentySevenVoxels) {
  BoundingCylinder c;
  c.radius_mm = 100;
  c.bottom_mm = 0;
  c.top_mm = 200;
  const double voxel = 10;
  NeighbourhoodBits<uint8_t> bits(c, voxel);
  std::mt19937 random(7);
  std::uniform_real_distribution<double> xy(-110, 110), z(-10, 210);
  struct Marked {
    Eigen::Vector3d point;
    uint8_t bits;
  };
  std::vector<Marked> marked;
  for (int i = 0; i < 300; ++i) {
    const Marked m{{xy(random), xy(random), z(random)}, static_cast<uint8_t>(1u << (i % 8))};
    bits.Add(m.point, m.bits);
    marked.push_back(m);
  }
  bits.Spread(/*threads=*/3);
  const Eigen::Vector3d origin(-100, -100, 0);
  const auto cell = [&](const Eigen::Vector3d& p) {
    return ((p - origin) / voxel).array().floor().cast<int>().matrix().eval();
  };
  size_t set = 0;
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Vector3d query(xy(random), xy(random), z(random));
    uint8_t expected = 0;
    const bool inside = (cell(query).array() >= 0).all() &&
                        (cell(query).array() <= Eigen::Array3i(20, 20, 20)).all();
    if (inside) {
      for (const Marked& m : marked)
        if ((cell(m.point) - cell(query)).cwiseAbs().maxCoeff() <= 1) expected |= m.bits;
    }
    ASSERT_EQ(bits.At(query), expected) << query.transpose();
    set += expected != 0;
  }
  EXPECT_GT(set, 500u);
}

TEST(VoxelBox, NeighbourhoodIsTheVoxelsAroundAPointInsideTheBox) {
  BoundingCylinder c;
  c.radius_mm = 50;
  c.bottom_mm = 0;
  c.top_mm = 100;
  const VoxelBox box(c, 10);
  int inside = 0, corner = 0;
  box.ForNeighbourhood({0, 0, 50}, [&](size_t) { ++inside; });
  box.ForNeighbourhood({-49, -49, 1}, [&](size_t) { ++corner; });
  EXPECT_EQ(inside, 27);
  EXPECT_EQ(corner, 8);
  EXPECT_FALSE(box.Index({0, 0, -1}).has_value());
  EXPECT_EQ(box.Index({0, 0, 50}), box.Index({9.9, 0, 50}));
  EXPECT_NE(box.Index({0, 0, 50}), box.Index({10.1, 0, 50}));
}

}  // namespace
}  // namespace mirrorscan::reconstruction

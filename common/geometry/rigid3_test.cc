#include "common/geometry/rigid3.h"

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

TEST(Rigid3Test, InverseAndComposition) {
  const Rigid3d b_from_a(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
      {10, -20, 30});
  const Rigid3d c_from_b(Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d::UnitZ())),
                         {0, 5, 0});
  const Eigen::Vector3d p(1, 2, 3);
  EXPECT_LT(((c_from_b * b_from_a) * p - c_from_b * (b_from_a * p)).norm(), 1e-12);
  EXPECT_LT((b_from_a.Inverse() * (b_from_a * p) - p).norm(), 1e-12);
  EXPECT_LT((b_from_a.Matrix() * p.homogeneous() - b_from_a * p).norm(), 1e-12);
}

}  // namespace
}  // namespace mirrorscan

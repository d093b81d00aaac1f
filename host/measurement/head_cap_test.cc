// The head cap's fit against analytic heads whose top is known: an ellipsoid, one longer
// behind the crown than in front, a flatter profile; each with the top unseen and the
// back open as the cabinet leaves it.
#include "host/measurement/head_cap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

namespace mirrorscan::measurement {
namespace {

struct Head {
  double a = 80.5, b_front = 98.0, b_back = 98.0, c = 115.5;
  double profile = 2.0;  // (x/a)^2 + (y/b)^2 + |z/c|^profile = 1
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;  // nodding forward (the front down) for > 0
  Eigen::Vector3d centre = Eigen::Vector3d(0.0, 0.0, 1634.5);
};

// The head's surface, rings every `dz` from `from` below the top of its own frame up to it,
// points every ~`step` round, turned to the world.
std::vector<Eigen::Vector3d> Surface(const Head& h, double from, double dz, double step) {
  std::vector<Eigen::Vector3d> points;
  const double yaw = h.yaw_deg * std::numbers::pi / 180.0;
  const double pitch = h.pitch_deg * std::numbers::pi / 180.0;
  const Eigen::Matrix3d turn = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  const int rings = static_cast<int>(std::ceil(from / dz));
  for (int i = 0; i <= rings; ++i) {
    const double z = std::min(h.c - from + i * dz, h.c);  // the last ring at the top
    const double scale = std::sqrt(std::max(0.0, 1.0 - std::pow(std::abs(z / h.c), h.profile)));
    const int n = std::max(8, static_cast<int>(2.0 * std::numbers::pi * 100.0 * scale / step));
    for (int k = 0; k < n; ++k) {
      const double t = 2.0 * std::numbers::pi * k / n;
      const double y = (std::sin(t) < 0.0 ? h.b_front : h.b_back) * scale * std::sin(t);
      points.push_back(h.centre + turn * Eigen::Vector3d(h.a * scale * std::cos(t), y, z));
    }
  }
  return points;
}

// The highest point of the head's surface.
Eigen::Vector3d TrueTop(const Head& h) {
  Eigen::Vector3d top(0, 0, -1e18);
  for (const Eigen::Vector3d& p : Surface(h, 15.0, 0.02, 0.5)) {
    if (p.z() > top.z()) top = p;
  }
  return top;
}

// Points every ~2 mm on the head's surface over the 50 mm below its top, without a hole
// of `hole_mm` round the top (horizontally) and, for `back_open_mm` below the top, without
// the back (as the mirrors leave it: nothing behind 7 mm in front of the crown).
std::vector<Eigen::Vector3d> Cap(const Head& h, double hole_mm, double back_open_mm,
                                 const Eigen::Vector3d& top) {
  const double yaw = h.yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d back(-std::sin(yaw), std::cos(yaw));
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& p : Surface(h, 120.0, 0.5, 2.0)) {
    const Eigen::Vector2d from_top = (p - top).head<2>();
    if (p.z() < top.z() - 50.0 || from_top.norm() < hole_mm) continue;
    if (from_top.dot(back) > -7.0 && p.z() > top.z() - back_open_mm) continue;
    points.push_back(p);
  }
  return points;
}

struct CapResult {
  double error = 0.0;  // fitted top - true top
  double rise = 0.0;   // true top - the highest point fitted
};

CapResult FitCap(const Head& h, double hole_mm, double back_open_mm) {
  const Eigen::Vector3d top = TrueTop(h);
  const std::vector<Eigen::Vector3d> points = Cap(h, hole_mm, back_open_mm, top);
  const double yaw = h.yaw_deg * std::numbers::pi / 180.0;
  const std::optional<HeadCapFit> fit =
      FitHeadCap(points, Eigen::Vector2d(std::cos(yaw), std::sin(yaw)));
  EXPECT_TRUE(fit);
  CapResult result;
  result.error = fit ? fit->top.z() - top.z() : 1e9;
  double highest = -1e18;
  for (const Eigen::Vector3d& p : points) highest = std::max(highest, p.z());
  result.rise = top.z() - highest;
  return result;
}

TEST(HeadCapTest, AnEllipsoidsTopComesBackFromItsCapAlone) {
  const Head h;
  EXPECT_NEAR(FitCap(h, 30.0, 0.0).error, 0.0, 0.02);
  EXPECT_NEAR(FitCap(h, 45.0, 30.0).error, 0.0, 0.02);
}

// Longer behind the crown than in front: the front half's profile gives the top, whatever
// the back's depth; a model with one depth for both halves does not (planted, it is
// 0.4 mm low, and 1.3 mm high with the back open).
TEST(HeadCapTest, AHeadLongerBehindThanInFrontHasItsTopAboveTheCentre) {
  Head h;
  h.b_front = 90.0;
  h.b_back = 106.0;
  h.yaw_deg = 30.0;
  h.centre = Eigen::Vector3d(50.0, -20.0, 1484.5);
  EXPECT_NEAR(FitCap(h, 30.0, 0.0).error, 0.0, 0.02);
  EXPECT_NEAR(FitCap(h, 30.0, 30.0).error, 0.0, 0.02);
}

// Not an ellipsoid (a flatter top): the model's own error, within what docs/measurement.md
// tables for this profile (+0.2 mm for a hole 30 mm round, under +0.5 mm for 45 mm with
// the back open).
TEST(HeadCapTest, AFlatterTopIsWithinTheModelsTabledError) {
  Head h;
  h.profile = 2.5;
  for (const auto& [hole_mm, back_open_mm] : {std::pair(30.0, 0.0), std::pair(45.0, 30.0)}) {
    const double error = FitCap(h, hole_mm, back_open_mm).error;
    EXPECT_GT(error, 0.0) << hole_mm;
    EXPECT_LT(error, 0.5) << hole_mm;
  }
}

// The model's error on heads it does not describe, tabled in docs/measurement.md (fitted
// top - true top, mm; the true top's rise above the highest point fitted in brackets).
TEST(HeadCapTest, ModelErrorTable) {
  struct Case {
    const char* name;
    Head head;
  };
  std::vector<Case> cases;
  const auto add = [&](const char* name, double profile, double b_front, double b_back,
                       double pitch) {
    Head h;
    h.profile = profile;
    h.b_front = b_front;
    h.b_back = b_back;
    h.pitch_deg = pitch;
    cases.push_back({name, h});
  };
  add("ellipsoid", 2.0, 98, 98, 0);
  add("profile ^2.2", 2.2, 98, 98, 0);
  add("profile ^2.5", 2.5, 98, 98, 0);
  add("profile ^3", 3.0, 98, 98, 0);
  add("longer behind, 90 / 106", 2.0, 90, 106, 0);
  add("pitched 10 deg forward", 2.0, 98, 98, 10);
  add("pitched 10 deg back", 2.0, 98, 98, -10);
  add("pitched 20 deg forward", 2.0, 98, 98, 20);
  add("90 / 106, pitched 10 deg forward", 2.0, 90, 106, 10);
  std::printf(
      "| head | hole 30 mm | 30 mm, back open 30 mm | 45 mm | 45 mm, back open | 60 mm | 60 mm, "
      "back open |\n|---|---|---|---|---|---|---|\n");
  for (const Case& c : cases) {
    std::printf("| %s |", c.name);
    for (const double hole : {30.0, 45.0, 60.0}) {
      for (const double back : {0.0, 30.0}) {
        const CapResult r = FitCap(c.head, hole, back);
        std::printf(" %+.2f (%.0f) |", r.error, r.rise);
        // What docs/measurement.md states for a top within 20 mm of the points fitted.
        if (r.rise <= 20.0 && c.head.profile <= 2.5) {
          EXPECT_LT(std::abs(r.error), c.head.pitch_deg == 0.0 ? 0.6 : 2.5)
              << c.name << ", hole " << hole << ", back " << back;
        }
      }
    }
    std::printf("\n");
  }
}

TEST(HeadCapTest, TooFewPointsGiveNoFit) {
  EXPECT_FALSE(FitHeadCap({Eigen::Vector3d(0, 0, 1700), Eigen::Vector3d(1, 0, 1699)},
                          Eigen::Vector2d::UnitX()));
}

}  // namespace
}  // namespace mirrorscan::measurement

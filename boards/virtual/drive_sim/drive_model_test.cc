#include "boards/virtual/drive_sim/drive_model.h"

#include <gtest/gtest.h>

namespace mirrorscan::virtual_cabinet {
namespace {

constexpr int64_t kSecond = 1'000'000'000;

DriveModel Homed(int64_t& t) {
  DriveModelConfig config;
  config.initial_position_mm = 40.0;
  config.homing_speed_mm_s = 100.0;
  DriveModel model(config, t);
  model.SetEnabled(true, t);
  model.Home(t);
  t += kSecond;  // 40 mm at 100 mm/s takes 0.4 s
  model.Advance(t);
  return model;
}

TEST(DriveModelTest, HomesToZeroAtTheHomingSpeed) {
  DriveModelConfig config;
  config.initial_position_mm = 40.0;
  config.homing_speed_mm_s = 100.0;
  DriveModel model(config, 0);
  model.SetEnabled(true, 0);
  model.Home(0);
  model.Advance(kSecond / 10);
  EXPECT_NEAR(model.state().position_mm, 30.0, 1e-9);
  EXPECT_TRUE(model.state().moving);
  EXPECT_FALSE(model.state().homed);
  model.Advance(kSecond);
  EXPECT_EQ(model.state().position_mm, 0.0);
  EXPECT_FALSE(model.state().moving);
  EXPECT_TRUE(model.state().homed);
}

TEST(DriveModelTest, MovesAtTheSetSpeedAndStopsAtTheTarget) {
  int64_t t = 0;
  DriveModel model = Homed(t);
  model.SetSpeed(250.0, t);
  model.Start(1000.0, t);
  model.Advance(t + 2 * kSecond);
  EXPECT_NEAR(model.state().position_mm, 500.0, 1e-9);
  model.Advance(t + 10 * kSecond);
  EXPECT_EQ(model.state().position_mm, 1000.0);
  EXPECT_FALSE(model.state().moving);
  // Back down, stopped half-way.
  t += 10 * kSecond;
  model.Start(0.0, t);
  model.Stop(t + kSecond);
  model.Advance(t + 5 * kSecond);
  EXPECT_NEAR(model.state().position_mm, 750.0, 1e-9);
  EXPECT_FALSE(model.state().moving);
}

// Where the slide was at an earlier time: at rest before the move began, then on its way.
TEST(DriveModelTest, PositionAtAnEarlierTime) {
  int64_t t = 0;
  DriveModel model = Homed(t);
  model.SetSpeed(200.0, t);
  const int64_t start = t + kSecond / 2;
  model.Advance(start);
  model.Start(1000.0, start);
  model.Advance(start + 2 * kSecond);
  const DriveModelState& s = model.state();
  EXPECT_NEAR(s.position_mm, 400.0, 1e-9);
  EXPECT_EQ(s.PositionAt(start + 2 * kSecond), s.position_mm);
  EXPECT_NEAR(s.PositionAt(start + kSecond), 200.0, 1e-9);
  EXPECT_NEAR(s.PositionAt(start + kSecond / 100), 2.0, 1e-9);
  EXPECT_EQ(s.PositionAt(start - kSecond / 10), 0.0);           // still at rest, not -20 mm
  EXPECT_EQ(s.PositionAt(start + 3 * kSecond), s.position_mm);  // no later than now
  // Homing back down runs at the homing speed (100 mm/s), which the line follows too.
  const int64_t home = start + 2 * kSecond;
  model.Home(home);
  model.Advance(home + kSecond);
  EXPECT_NEAR(model.state().position_mm, 300.0, 1e-9);
  EXPECT_NEAR(model.state().PositionAt(home + kSecond / 2), 350.0, 1e-9);
}

TEST(DriveModelTest, RefusesBadCommandsWithAFault) {
  DriveModel cold(DriveModelConfig{}, 0);
  cold.Home(0);
  EXPECT_EQ(cold.state().fault_code, kDriveFaultNotEnabled);
  cold.ResetFault(0);
  cold.SetEnabled(true, 0);
  cold.SetSpeed(100.0, 0);
  cold.Start(500.0, 0);
  EXPECT_EQ(cold.state().fault_code, kDriveFaultNotHomed);

  int64_t t = 0;
  DriveModel model = Homed(t);
  model.SetSpeed(100.0, t);
  model.Start(5000.0, t);
  EXPECT_TRUE(model.state().fault);
  EXPECT_EQ(model.state().fault_code, kDriveFaultOutsideTravel);
  model.Start(100.0, t);  // ignored while faulted
  EXPECT_FALSE(model.state().moving);
  model.ResetFault(t);
  model.Start(100.0, t);
  EXPECT_TRUE(model.state().moving);
}

TEST(DriveModelTest, InjectedFaultStopsAndLatchesTheCode) {
  int64_t t = 0;
  DriveModel model = Homed(t);
  model.SetSpeed(100.0, t);
  model.Start(1000.0, t);
  model.InjectFault(0x2310, t + kSecond);
  model.Advance(t + 3 * kSecond);
  EXPECT_NEAR(model.state().position_mm, 100.0, 1e-9);
  EXPECT_FALSE(model.state().moving);
  EXPECT_TRUE(model.state().fault);
  EXPECT_EQ(model.state().fault_code, 0x2310);
}

TEST(DriveModelTest, DisablingStopsAndInterruptedHomingIsNotHomed) {
  DriveModelConfig config;
  config.initial_position_mm = 40.0;
  config.homing_speed_mm_s = 100.0;
  DriveModel model(config, 0);
  model.SetEnabled(true, 0);
  model.Home(0);
  model.SetEnabled(false, kSecond / 10);
  model.Advance(kSecond);
  EXPECT_NEAR(model.state().position_mm, 30.0, 1e-9);
  EXPECT_FALSE(model.state().homed);
  EXPECT_FALSE(model.state().moving);
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

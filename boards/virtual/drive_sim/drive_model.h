#pragma once

#include <cstdint>

namespace mirrorscan::virtual_cabinet {

// Fault codes the simulated drive raises by itself (an injected fault uses any code).
inline constexpr int kDriveFaultNotEnabled = 0x10;     // home/start while disabled
inline constexpr int kDriveFaultNotHomed = 0x11;       // start before homing
inline constexpr int kDriveFaultOutsideTravel = 0x12;  // target outside the travel limits
inline constexpr int kDriveFaultBadSpeed = 0x13;       // speed 0 or above the maximum

struct DriveModelConfig {
  double min_mm = 0.0;  // travel limits (hard stops)
  double max_mm = 2000.0;
  double max_speed_mm_s = 1000.0;
  double homing_speed_mm_s = 200.0;
  double initial_position_mm = 100.0;  // where the slide is at power-up (not homed)
};

struct DriveModelState {
  int64_t time_ns = 0;  // steady clock time of this state
  double position_mm = 0.0;
  double speed_mm_s = 0.0;  // the set speed (homing uses homing_speed_mm_s)
  double goal_mm = 0.0;     // where the current move ends
  bool enabled = false;
  bool homed = false;
  bool homing = false;
  bool moving = false;
  bool fault = false;
  int fault_code = 0;
  // When and where the current (or last) move began.
  int64_t move_start_ns = 0;
  double move_start_mm = 0.0;

  // Where the slide was at `time` (at most time_ns): at rest at move_start_mm before the
  // current move began, then at its constant speed. A virtual camera renders a frame after
  // its exposure and asks this for the exposure time.
  double PositionAt(int64_t time) const;
};

// A slide without acceleration: it moves at the set speed from the command until the
// goal, integrated on the caller's clock (nanoseconds). Pure logic, no I/O, so it is
// tested with explicit times; DriveSim drives it from a steady clock.
class DriveModel {
 public:
  DriveModel(const DriveModelConfig& config, int64_t now_ns);

  void Advance(int64_t now_ns);  // integrates the motion up to now (never backwards)

  // Each command first advances to now_ns.
  void SetEnabled(bool on, int64_t now_ns);  // disabling stops
  void SetSpeed(double mm_per_s, int64_t now_ns);
  void Home(int64_t now_ns);  // moves to 0 at the homing speed, then homed
  void Start(double target_mm, int64_t now_ns);
  void Stop(int64_t now_ns);
  void ResetFault(int64_t now_ns);
  void InjectFault(int code, int64_t now_ns);  // stops at once and latches the code

  const DriveModelState& state() const { return state_; }
  const DriveModelConfig& config() const { return config_; }

 private:
  void Fault(int code);
  void MoveTo(double goal_mm);

  DriveModelConfig config_;
  DriveModelState state_;
};

}  // namespace mirrorscan::virtual_cabinet

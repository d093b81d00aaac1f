#include "boards/virtual/drive_sim/drive_model.h"

#include <algorithm>
#include <cmath>

namespace mirrorscan::virtual_cabinet {

DriveModel::DriveModel(const DriveModelConfig& config, int64_t now_ns) : config_(config) {
  state_.time_ns = now_ns;
  state_.position_mm = std::clamp(config.initial_position_mm, config.min_mm, config.max_mm);
  state_.goal_mm = state_.position_mm;
}

void DriveModel::Advance(int64_t now_ns) {
  if (now_ns <= state_.time_ns) return;
  const double dt = static_cast<double>(now_ns - state_.time_ns) * 1e-9;
  state_.time_ns = now_ns;
  if (!state_.moving) return;
  const double speed = state_.homing ? config_.homing_speed_mm_s : state_.speed_mm_s;
  const double remaining = state_.goal_mm - state_.position_mm;
  const double step = speed * dt;
  if (step >= std::abs(remaining)) {
    state_.position_mm = state_.goal_mm;
    state_.moving = false;
    if (state_.homing) {
      state_.homing = false;
      state_.homed = true;
    }
  } else {
    state_.position_mm += std::copysign(step, remaining);
  }
}

void DriveModel::Fault(int code) {
  state_.moving = false;
  state_.homing = false;
  state_.fault = true;
  state_.fault_code = code;
}

void DriveModel::MoveTo(double goal_mm) {
  state_.goal_mm = goal_mm;
  state_.moving = goal_mm != state_.position_mm;
  state_.move_start_ns = state_.time_ns;
  state_.move_start_mm = state_.position_mm;
}

double DriveModelState::PositionAt(int64_t time) const {
  if (!moving || time >= time_ns) return position_mm;
  if (time <= move_start_ns) return move_start_mm;
  // Constant speed since the move began: on the line from its start to now.
  const double w =
      static_cast<double>(time - move_start_ns) / static_cast<double>(time_ns - move_start_ns);
  return move_start_mm + w * (position_mm - move_start_mm);
}

void DriveModel::SetEnabled(bool on, int64_t now_ns) {
  Advance(now_ns);
  state_.enabled = on;
  if (!on) {
    state_.moving = false;
    state_.homing = false;
  }
}

void DriveModel::SetSpeed(double mm_per_s, int64_t now_ns) {
  Advance(now_ns);
  if (mm_per_s == state_.speed_mm_s) return;
  if (mm_per_s > config_.max_speed_mm_s || (state_.moving && !state_.homing && mm_per_s <= 0)) {
    Fault(kDriveFaultBadSpeed);
    return;
  }
  state_.speed_mm_s = mm_per_s;
}

void DriveModel::Home(int64_t now_ns) {
  Advance(now_ns);
  if (state_.fault) return;
  if (!state_.enabled) return Fault(kDriveFaultNotEnabled);
  state_.homed = false;
  state_.homing = true;
  MoveTo(0.0);
  if (!state_.moving) {  // already at the reference
    state_.homing = false;
    state_.homed = true;
  }
}

void DriveModel::Start(double target_mm, int64_t now_ns) {
  Advance(now_ns);
  if (state_.fault) return;
  if (!state_.enabled) return Fault(kDriveFaultNotEnabled);
  if (!state_.homed) return Fault(kDriveFaultNotHomed);
  if (target_mm < config_.min_mm || target_mm > config_.max_mm) {
    return Fault(kDriveFaultOutsideTravel);
  }
  if (!(state_.speed_mm_s > 0.0)) return Fault(kDriveFaultBadSpeed);
  state_.homing = false;
  MoveTo(target_mm);
}

void DriveModel::Stop(int64_t now_ns) {
  Advance(now_ns);
  if (state_.homing) state_.homing = false;  // an interrupted homing leaves it not homed
  state_.moving = false;
  state_.goal_mm = state_.position_mm;
}

void DriveModel::ResetFault(int64_t now_ns) {
  Advance(now_ns);
  state_.fault = false;
  state_.fault_code = 0;
}

void DriveModel::InjectFault(int code, int64_t now_ns) {
  Advance(now_ns);
  Fault(code);
}

}  // namespace mirrorscan::virtual_cabinet

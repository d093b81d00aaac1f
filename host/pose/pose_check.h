#pragma once
// The pose check (docs/pose-check.md): after a scan, from its point cloud, how the person
// stood (feet spread, arm abduction left and right, yaw, lean, head turn, head height)
// against the standard scanning posture (docs/scanning-posture.md), and what a shop
// assistant should say for a rescan when it is off.
//
// World frame (DESIGN.md): mm, z up from the floor, the camera at -y looking +y, x to the
// right as the camera sees it. The person faces the camera: their left is +x.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/config/calibration.h"
#include "common/mesh/point_cloud.h"

namespace mirrorscan::pose {

// How high the cabinet scans: the mirrors' top (a point above it is seen and lit only from
// the front) and the top laser's height at the sweep's end. Unknown parts are empty.
struct CabinetReach {
  std::optional<double> mirror_top_mm;
  std::optional<double> laser_top_mm;
  // The lower of the known limits, or empty; and which one it is ("mirrors", "lasers").
  std::optional<double> top_mm() const;
  std::string limited_by() const;
};

// The mirrors' top from the calibration's mirror corners (else `board_mirror_top_mm`); the
// top laser from `sweep_end_mm` (board.json "scan"), the calibration's slide readback
// offset and its highest laser's offset.
CabinetReach ReachOf(const Calibration& calibration, std::optional<double> sweep_end_mm,
                     std::optional<double> board_mirror_top_mm = std::nullopt);

// The protocol's tolerances (docs/pose-check.md says why each is what it is).
struct PoseTolerances {
  double arm_min_deg = 15.0;  // the posture asks 20-30 degrees; the population holds 25-40
  double arm_max_deg = 45.0;
  double yaw_max_deg = 10.0;        // |yaw| from facing the camera
  double lean_max_deg = 3.0;        // |lean| about the ankles
  double head_turn_max_deg = 15.0;  // |head turn| from the body's front
  double feet_min_ratio = 0.85;     // feet spread / the legs' spread at the hips
  double feet_max_ratio = 1.6;
  // The top of the head may rise this far above the reach: no camera sees the crown anyway
  // (it is extrapolated), and the estimate of it is good to about 20 mm.
  double reach_margin_mm = 20.0;
};

struct PoseOptions {
  CabinetReach reach;
  PoseTolerances tolerances;
};

// A figure and whether it is within the protocol; `value` empty when it could not be
// measured, `note` then says why.
struct PoseFigure {
  std::optional<double> value;
  bool ok = true;
  std::string note;
};

struct PoseReport {
  bool checked = false;  // false: not a standing person (`reason`); no figures then
  std::string reason;
  // Where the person stands: the ankles' midpoint on the floor (world x, y).
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
  PoseFigure feet_spread_mm;  // between the ankles' centres
  PoseFigure hip_spread_mm;   // between the legs' axes at hip height (the reference)
  std::array<PoseFigure, 2> arm_abduction_deg;  // [left, right]: the person's own sides
  PoseFigure yaw_deg;        // the body's front from facing the camera, + turned to its left
  PoseFigure lean_deg;       // + forward, - back, about the ankles
  PoseFigure head_turn_deg;  // the head from the body's front, + to its left
  PoseFigure head_top_mm;    // the top of the head, extrapolated above the highest point seen
  double head_top_seen_mm = 0.0;
  std::string yaw_from;  // "legs" or "trunk"
  bool within_protocol = false;
  std::vector<std::string> advice;  // sentences a shop assistant can say, in order
};

// Checks the pose from the cloud's points (world, mm). Robust to holes (under the arms,
// between the thighs, the top of the head), some stray points and wherever the person
// stands near the origin.
PoseReport CheckPose(const std::vector<Eigen::Vector3d>& points, const PoseOptions& options = {});
PoseReport CheckPose(const PointCloud& cloud, const PoseOptions& options = {});

// summary.json's "pose".
nlohmann::json ToJson(const PoseReport& report, const PoseOptions& options);

}  // namespace mirrorscan::pose

#pragma once
// What a reconstruction reports: how each peak was decided or why it was dropped, where the
// laser heights came from, points per camera, view and laser, and the stages' timings; as
// JSON (`mirrorscan reconstruct --json`, summary.json) and as text.
#include <chrono>
#include <cstddef>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace mirrorscan::reconstruction {

struct LaserHeightSummary {
  std::string source;  // "panels" or "readback"
  std::string reason;  // why the readback was used, when it was
  double speed_mm_s = 0.0;
  double height_at_t0_mm = 0.0;
  std::vector<double> offsets_mm;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double panel_residual_rms_mm = 0.0;
  size_t panel_points = 0;
  // Readback against the fitted heights (frames with a readback).
  size_t readback_frames = 0;
  double readback_offset_mm = 0.0;
  double readback_max_error_mm = 0.0;
  size_t readback_frames_off = 0;
};

struct IcpSummary {
  bool ran = false;
  struct Step {
    std::string what;  // e.g. "upper/left against upper/center"
    double rmse_before_mm = 0.0, rmse_after_mm = 0.0;
    double rotation_deg = 0.0, translation_mm = 0.0;
    bool applied = false;
  };
  std::vector<Step> steps;
};

struct ReconstructSummary {
  std::string archive_message;  // the reader's report
  bool archive_complete = false;
  size_t frames = 0;  // frames with lasers on used
  size_t peaks = 0;
  LaserHeightSummary laser_height;
  // How each peak's laser/view was decided, or why it was dropped.
  // Exactly one hypothesis that another camera saw too.
  size_t decided_by_stereo = 0;
  size_t decided_by_cylinder = 0;  // one hypothesis inside the bounding cylinder's core
  // Exactly one hypothesis near points the cylinder decided (the volume the scan carves).
  size_t decided_by_volume = 0;
  size_t decided_by_column_count = 0;
  size_t decided_by_label_vote = 0;
  size_t dropped_panel = 0;      // the laser line on a panel (laser-height data)
  size_t dropped_no_ray = 0;     // undistortion failed / ray misses everything
  size_t dropped_still = 0;      // stays put across frames: the ambient scene, no laser line
  size_t dropped_outside = 0;    // no hypothesis inside the bounding cylinder
  size_t dropped_floor = 0;      // the floor lit by a laser at its height
  size_t dropped_ambiguous = 0;  // several hypotheses and nothing to decide
  size_t dropped_conflict = 0;   // its label's vote is not among its hypotheses
  // Its label's vote lands nowhere near (~10–20 mm) a peak decided without the vote.
  size_t dropped_unsupported = 0;
  // The other lasers at its pixel see another surface, or other views see through it.
  size_t dropped_seen_through = 0;
  size_t dropped_flat_angle = 0;    // ray too flat to the laser plane
  size_t dropped_other_camera = 0;  // another camera sees the place at a better angle
  size_t dropped_stripe_end = 0;
  size_t dropped_outlier = 0;  // off its (column, frame) neighbours and not on the surface
  size_t dropped_low_confidence = 0;
  size_t dropped_off_surface = 0;  // a weak point the confident ones around it do not carry
  // A flat ray's point off the surface another camera sees more squarely.
  size_t dropped_flat_off_surface = 0;
  size_t double_bounce = 0;        // triangulated through both mirrors
  size_t points = 0;
  std::vector<size_t> points_per_camera;  // by FrameRecord::camera
  std::vector<size_t> points_per_view;    // by PointView
  std::vector<size_t> points_per_laser;
  IcpSummary icp;
  std::vector<std::string> warnings;
  // Seconds per stage, in order.
  std::vector<std::pair<std::string, double>> timings_s;
};

nlohmann::json SummaryJson(const ReconstructSummary& summary);
std::string SummaryText(const ReconstructSummary& summary);

// The stages' timings into the summary (timings_s, in order) and their start to the
// caller's progress callback.
class StageTimer {
 public:
  using Progress = std::function<void(const std::string& stage, double fraction)>;
  StageTimer(ReconstructSummary* summary, Progress progress)
      : summary_(summary), progress_(std::move(progress)) {}
  // Reports the stage's start (fraction 0; "done" is 1).
  void Start(const char* stage) const {
    if (progress_) progress_(stage, std::string(stage) == "done" ? 1.0 : 0.0);
  }
  // The time since the last lap (or since this timer was made) as the stage's.
  void Lap(const std::string& stage) {
    const auto now = std::chrono::steady_clock::now();
    summary_->timings_s.emplace_back(stage, std::chrono::duration<double>(now - last_).count());
    last_ = now;
  }

 private:
  ReconstructSummary* summary_;
  Progress progress_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

}  // namespace mirrorscan::reconstruction

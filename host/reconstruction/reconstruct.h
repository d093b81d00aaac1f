#pragma once
// Reconstruction (docs/reconstruction.md): every laser peak of a scan archive to a 3D point
// in the world frame through the calibrated cameras and mirrors. Laser heights per frame
// come from the lines on the panels (host/calibration/laser_height), the slide readback
// checks them and stands in where the panels are not seen. Each peak gets its view (the
// calibration's view regions, mirror rays reflected, rays that bounce in both mirrors
// followed through both) and its laser (bounding cylinder, column counting, then a
// majority vote over peaks that are neighbours in column and frame); then confidence,
// filters, normals from the (column, frame) grid and the merged cloud of every camera and
// view.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/config/calibration.h"
#include "common/mesh/point_cloud.h"
#include "common/scan_format/scan_format.h"

namespace mirrorscan::reconstruction {

// Bad input that makes a cloud impossible or untrustworthy (no header, no frames, a camera
// the calibration lacks, ...). The message is one line saying what is wrong.
class ReconstructError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The archive was made with another calibration than the one given.
class CalibrationMismatchError : public ReconstructError {
 public:
  using ReconstructError::ReconstructError;
};

// The cloud's types are the project's one point cloud (common/mesh/point_cloud.h).
using mirrorscan::CloudPoint;
using mirrorscan::DecidedBy;
using mirrorscan::PointCloud;
using mirrorscan::PointView;
const char* PointViewName(PointView view);
const char* DecidedByName(DecidedBy rule);

// A vertical cylinder about the cabinet's axis that holds the subject: a laser hypothesis
// whose point falls outside it is rejected, and so is any output point. Within its core
// (core_radius_mm) stands the body itself: a peak with one hypothesis there and no other
// camera's word against it is decided alone; out to radius_mm reach the hands.
struct BoundingCylinder {
  Eigen::Vector2d center_mm = Eigen::Vector2d::Zero();
  double radius_mm = 650.0;
  double core_radius_mm = 450.0;
  double bottom_mm = 20.0;
  double top_mm = 2100.0;
  bool Contains(const Eigen::Vector3d& point) const;
  bool CoreContains(const Eigen::Vector3d& point) const;
  // Below the bottom, down to the floor (z 0) and a little under it.
  bool OnFloor(const Eigen::Vector3d& point) const;
  // From board.json's optional "reconstruction": {"bounding_cylinder": {"radius_mm",
  // "core_radius_mm", "bottom_mm", "top_mm", "center_mm"}}; defaults for missing keys. ConfigError
  // naming the file and key on a bad value.
  static BoundingCylinder FromBoard(const std::filesystem::path& board_json);
};

struct ReconstructOptions {
  BoundingCylinder cylinder;
  // Refuse an archive made with another calibration (CalibrationMismatchError) unless this
  // is set; then it is a warning.
  bool allow_calibration_mismatch = false;
  // SHA-256 (hex) of the calibration file's bytes, compared with the archive header's
  // `calibration_sha256` (what the device records); empty: not compared.
  std::string calibration_file_sha256;
  // Laser heights from the panel lines; false: from the slide readback alone.
  bool laser_height_from_panels = true;
  double panel_margin_mm = 120.0;
  // Frames whose panel-measured height is further than this from the fitted line, or whose
  // readback disagrees by more, are reported.
  double readback_tolerance_mm = 1.0;
  // Stereo: a hypothesis is confirmed when another camera, at the nearest moment, has one of
  // the same laser within this distance (the planes' travel between the two frames added).
  bool stereo = true;
  double stereo_max_mm = 3.0;
  // Rays meeting the laser plane flatter than this give no useful depth. 5 degrees keeps
  // the lower camera's rays of 6-8 degrees (the mannequin's 3,174 points there: mean
  // 0.17 mm, p99 1.13 mm, none beyond 5 mm of the surface; docs/reconstruction.md).
  double min_ray_plane_angle_deg = 5.0;
  // Merging cameras: a point is dropped where another camera has points within a 10 mm
  // voxel whose ray–plane angle's sine is this many times larger (0: keep every camera's,
  // the default: both cameras' points are as good once the flat rays are gone, and
  // dropping one camera's loses a fifth of the surface's points).
  double prefer_camera_ratio = 0.0;
  // No subject stands closer than this in front of a mirror's glass: there every camera's
  // reflected rays run close together and phantom points confirm each other.
  double mirror_clearance_mm = 80.0;
  // Free space (docs/reconstruction.md): a point is dropped where the other lasers at its
  // own pixel (within free_space_rows_px rows) all see another surface, or where other views
  // look through it (see further by more than free_space_mm, per row off that much more)
  // and no view sees it.
  bool free_space_check = true;
  double free_space_rows_px = 3.0;
  double free_space_mm = 20.0;
  // Neighbours in (column, frame) belong to one label when their rows differ less than this.
  double label_max_row_step_px = 3.0;
  double label_max_frame_step_px = 20.0;
  // Filters, each switchable.
  bool smooth_3x3 = true;       // the paper's 3×3 average in (column, frame)
  bool remove_outliers = true;  // statistical, against the (column, frame) neighbours
  double outlier_sigmas = 4.0;
  double outlier_min_mm = 0.5;  // never an outlier closer than this to its neighbours
  // The distance from the neighbours' midpoint less this share of their distance apart.
  double outlier_chord_share = 0.1;
  // The last columns of a stripe leave the plane's trace; they get a low confidence and are
  // dropped only when asked.
  bool drop_stripe_ends = false;
  int stripe_end_columns = 2;
  bool clip_to_cylinder = true;
  // Points whose confidence is below this are dropped: the last column of a stripe with a
  // weak peak, a ray meeting the plane at a grazing angle, where the measured error grows
  // (docs/reconstruction.md: 0.15 leaves no mannequin point beyond 5 mm of its surface but
  // drops 4 % of its points and 7 % of the cuboid's). 0, the default, keeps every point.
  double min_confidence = 0.0;
  // Surface support: a point whose confidence is below surface_check_confidence (a stripe's
  // end, a grazing ray: where blur mixes the light of two surfaces and the peak lands in
  // the air between them) is dropped when it lies further than surface_check_max_mm from
  // the plane of the confident points within surface_check_radius_mm, and by more than 3
  // times that plane's RMS (at an edge or a fold the plane says nothing); or when only the
  // column count or the label vote decided it and no confident point is near. It also
  // judges the outlier test's points, which it keeps only within surface_check_outlier_mm
  // of that plane (no RMS allowance) and with at least 6 confident points within the
  // radius; without the check the outlier test drops them all.
  bool surface_check = true;
  double surface_check_confidence = 0.15;
  double surface_check_radius_mm = 12.0;
  double surface_check_max_mm = 3.0;
  double surface_check_outlier_mm = 1.0;
  // Optional ICP refinement of mirror views and the lower camera against the rest
  // (reported; off by default).
  bool icp = false;
  // Worker threads for the per-peak and per-point stages (0: every core). The cloud is the
  // same for any number.
  int threads = 0;
  // Progress: a stage name and how far it is in [0, 1]. May be empty.
  std::function<void(const std::string& stage, double fraction)> progress;
};

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

struct Reconstruction {
  PointCloud cloud;
  ReconstructSummary summary;
};

// The archive's frames (lasers on) to a cloud. Throws CalibrationMismatchError,
// ReconstructError (no header, no frames with peaks, a camera or view the archive needs
// that the calibration lacks, no laser heights at all).
Reconstruction Reconstruct(const ScanArchive& archive, const Calibration& calibration,
                           const ReconstructOptions& options = {});

nlohmann::json SummaryJson(const ReconstructSummary& summary);
std::string SummaryText(const ReconstructSummary& summary);

}  // namespace mirrorscan::reconstruction

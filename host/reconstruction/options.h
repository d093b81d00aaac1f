#pragma once
// What Reconstruct() may be told (docs/reconstruction.md names each stage's options).
#include <functional>
#include <string>

#include "host/reconstruction/bounding_cylinder.h"

namespace mirrorscan::reconstruction {

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
  // Rays meeting the laser plane flatter than this give no useful depth. The people's
  // cabinet's flattest rays, the lower camera's at 4-6 degrees, are good points (f01: mean
  // 1.2 mm, p99 2.5, none beyond 5 mm); dropping them at 5 degrees cost 1.3-1.6 points of
  // recall (docs/reconstruction.md).
  double min_ray_plane_angle_deg = 3.0;
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
  // radius; without the check the outlier test drops them all. At 1 mm it dropped right
  // points of the lower camera's flat rays, noisier than the rest (f01: recall of the
  // detected truth 99.07 -> 99.59 %, the 2,394 points kept 0.76 mm off on average).
  bool surface_check = true;
  double surface_check_confidence = 0.15;
  double surface_check_radius_mm = 12.0;
  double surface_check_max_mm = 3.0;
  double surface_check_outlier_mm = 2.0;
  // A point whose ray meets its plane flatter than flat_check_deg is judged by the confident
  // points of other cameras within the radius whose rays meet theirs flat_check_ratio times
  // more squarely: dropped (dropped.flat_off_surface) beyond surface_check_max_mm of their plane
  // and 3 times its RMS. The lower camera's top rows meet the planes at 4-10 degrees; a peak
  // 0.5 px off there is a point 5 mm off (f01, docs/reconstruction.md). 0: no such check.
  double flat_check_deg = 12.0;
  double flat_check_ratio = 1.5;
  // Optional ICP refinement of mirror views and the lower camera against the rest
  // (reported; off by default).
  bool icp = false;
  // Worker threads for the per-peak and per-point stages (0: every core). The cloud is the
  // same for any number.
  int threads = 0;
  // Progress: a stage name and how far it is in [0, 1]. May be empty.
  std::function<void(const std::string& stage, double fraction)> progress;

  // Throws std::invalid_argument naming the first option out of its range (Reconstruct()
  // calls it first). A core wider than the cylinder is allowed: the core is clipped to it.
  void Validate() const;
};

}  // namespace mirrorscan::reconstruction

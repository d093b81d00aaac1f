#include "host/reconstruction/options.h"

#include <cstdio>
#include <stdexcept>

namespace mirrorscan::reconstruction {

namespace {

// Written so that NaN fails every check.
void Require(bool ok, const char* option, double value, const char* range) {
  if (ok) return;
  char text[256];
  std::snprintf(text, sizeof(text), "reconstruction option %s is %g; it must be %s", option, value,
                range);
  throw std::invalid_argument(text);
}

}  // namespace

void ReconstructOptions::Validate() const {
  const BoundingCylinder& c = cylinder;
  Require(c.radius_mm > 0, "cylinder.radius_mm", c.radius_mm, "above 0");
  Require(c.core_radius_mm > 0, "cylinder.core_radius_mm", c.core_radius_mm, "above 0");
  Require(c.top_mm > c.bottom_mm, "cylinder.top_mm", c.top_mm, "above cylinder.bottom_mm");
  Require(panel_margin_mm >= 0, "panel_margin_mm", panel_margin_mm, "0 or more");
  Require(readback_tolerance_mm > 0, "readback_tolerance_mm", readback_tolerance_mm, "above 0");
  Require(stereo_max_mm > 0, "stereo_max_mm", stereo_max_mm, "above 0");
  Require(min_ray_plane_angle_deg >= 0 && min_ray_plane_angle_deg < 90, "min_ray_plane_angle_deg",
          min_ray_plane_angle_deg, "in [0, 90)");
  Require(prefer_camera_ratio >= 0, "prefer_camera_ratio", prefer_camera_ratio, "0 or more");
  Require(mirror_clearance_mm >= 0, "mirror_clearance_mm", mirror_clearance_mm, "0 or more");
  Require(free_space_rows_px >= 0, "free_space_rows_px", free_space_rows_px, "0 or more");
  Require(free_space_mm > 0, "free_space_mm", free_space_mm, "above 0");
  Require(label_max_row_step_px >= 0, "label_max_row_step_px", label_max_row_step_px, "0 or more");
  Require(label_max_frame_step_px >= 0, "label_max_frame_step_px", label_max_frame_step_px,
          "0 or more");
  Require(outlier_sigmas > 0, "outlier_sigmas", outlier_sigmas, "above 0");
  Require(outlier_min_mm >= 0, "outlier_min_mm", outlier_min_mm, "0 or more");
  Require(outlier_chord_share >= 0 && outlier_chord_share < 1, "outlier_chord_share",
          outlier_chord_share, "in [0, 1)");
  Require(stripe_end_columns >= 0, "stripe_end_columns", stripe_end_columns, "0 or more");
  Require(min_confidence >= 0 && min_confidence <= 1, "min_confidence", min_confidence,
          "in [0, 1]");
  Require(surface_check_confidence >= 0 && surface_check_confidence <= 1,
          "surface_check_confidence", surface_check_confidence, "in [0, 1]");
  Require(surface_check_radius_mm > 0, "surface_check_radius_mm", surface_check_radius_mm,
          "above 0");
  Require(surface_check_max_mm >= 0, "surface_check_max_mm", surface_check_max_mm, "0 or more");
  Require(surface_check_outlier_mm >= 0, "surface_check_outlier_mm", surface_check_outlier_mm,
          "0 or more");
  Require(flat_check_deg >= 0 && flat_check_deg < 90, "flat_check_deg", flat_check_deg,
          "in [0, 90)");
  Require(flat_check_ratio >= 1, "flat_check_ratio", flat_check_ratio, "1 or more");
  Require(threads >= 0, "threads", threads, "0 (every core) or more");
}

}  // namespace mirrorscan::reconstruction

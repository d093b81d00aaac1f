#include "host/calibration/checks.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace mirrorscan::calibration::internal {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

// The image-quality checks and their advice; true when every view can be solved.
bool CheckDetections(const CameraData& data, const CalibrationLimits& limits,
                     CalibrationResult& result) {
  bool solvable = true;
  const bool bright = data.report.white_dn >= limits.min_white_dn;
  result.checks.push_back({data.name + ".white_dn", data.report.white_dn,
                           ">= " + Format("%g", limits.min_white_dn), bright});
  if (!bright) {
    result.failures.push_back("camera " + data.name + ": the image is dark (brightest 1% at " +
                              Format("%.0f", data.report.white_dn) +
                              " DN); add light or raise the exposure or gain");
  }
  for (const ViewReport& v : data.report.views) {
    const std::string where = "camera " + data.name + ", " + ViewName(v.view) + " view";
    const int found = static_cast<int>(v.found.size());
    result.checks.push_back({data.name + "." + ViewName(v.view) + ".markers", double(found),
                             ">= " + std::to_string(limits.min_markers_per_view),
                             found >= limits.min_markers_per_view});
    if (found < limits.min_markers_per_view) {
      std::string advice;
      if (v.view == ViewId::kCenter) {
        advice = "place the target at its floor mark with panel 0 facing the camera";
      } else {
        advice = std::string("make sure the ") + ViewName(v.view) +
                 " mirror shows its panel of the target entirely (nothing in front of it, "
                 "target at its floor mark)";
      }
      result.failures.push_back(where + ": only " + std::to_string(found) + " of " +
                                std::to_string(found + v.missing.size()) + " markers found; " +
                                advice +
                                ", and check the light (too dark or too bright loses markers)");
    }
    solvable = solvable && found >= 4;
    if (found == 0) continue;
    const bool contrast_ok = v.contrast_dn >= limits.min_contrast_dn;
    result.checks.push_back({data.name + "." + ViewName(v.view) + ".contrast_dn", v.contrast_dn,
                             ">= " + Format("%g", limits.min_contrast_dn), contrast_ok});
    if (!contrast_ok) {
      result.failures.push_back(where + ": marker contrast " + Format("%.0f", v.contrast_dn) +
                                " DN is too low; add light or raise the exposure");
    }
    const bool sharp = v.edge_sigma_px <= limits.max_edge_sigma_px;
    result.checks.push_back({data.name + "." + ViewName(v.view) + ".edge_sigma_px", v.edge_sigma_px,
                             "<= " + Format("%g", limits.max_edge_sigma_px), sharp});
    if (!sharp) {
      result.failures.push_back(where + ": marker edges are blurred (σ " +
                                Format("%.2f", v.edge_sigma_px) +
                                " px); focus the camera and keep the target still");
    }
  }
  return solvable;
}

void CheckCoverage(const CameraReport& report, const CalibrationLimits& limits,
                   CalibrationResult& result) {
  const double coverage = report.coverage.fraction;
  const bool ok = coverage >= limits.min_lens_coverage;
  result.checks.push_back({report.name + ".lens_coverage", coverage,
                           ">= " + Format("%g", limits.min_lens_coverage), ok});
  if (ok) return;
  const std::string what = report.coverage.lens_fixed
                               ? "the lens calibration's chessboard corners and the target"
                               : "the target's markers (no lens calibration given)";
  result.failures.push_back(
      "camera " + report.name + ": the lens model rests on data on only " +
      Format("%.0f", 100.0 * coverage) + "% of the image (" + what + "; limit " +
      Format("%.0f", 100.0 * limits.min_lens_coverage) +
      "%), and the cabinet uses all of it: calibrate the lens with a chessboard held over the "
      "whole image, edges and corners included (mirrorscan calibrate-intrinsics), and give it "
      "with --intrinsics " +
      report.name + "=FILE");
}

// The mirrors' rectangles: from where the two planes meet, nominal width and height.
std::array<std::vector<Eigen::Vector3d>, 2> MirrorCorners(const std::array<Plane, 2>& mirrors,
                                                          const CalibrationSettings& s) {
  const Plane& l = mirrors[0];
  const Plane& r = mirrors[1];
  Eigen::Vector3d up = l.normal.cross(r.normal).normalized();
  if (up.z() < 0) up = -up;
  Eigen::Matrix2d a;
  a << l.normal.x(), l.normal.y(), r.normal.x(), r.normal.y();
  const double z = s.mirror_bottom_mm;
  const Eigen::Vector2d xy =
      a.inverse() * Eigen::Vector2d(-l.offset - l.normal.z() * z, -r.offset - r.normal.z() * z);
  const Eigen::Vector3d origin(xy.x(), xy.y(), z);
  std::array<std::vector<Eigen::Vector3d>, 2> corners;
  for (int side = 0; side < 2; ++side) {
    Eigen::Vector3d along = mirrors[side].normal.cross(up).normalized();
    if ((side == 0) != (along.x() < 0)) along = -along;
    corners[side] = {origin, origin + s.mirror_width_mm * along,
                     origin + s.mirror_width_mm * along + s.mirror_height_mm * up,
                     origin + s.mirror_height_mm * up};
  }
  return corners;
}

void CheckCabinet(const std::array<Plane, 2>& mirrors, const CalibrationSettings& s,
                  CalibrationResult& result) {
  const CalibrationLimits& limits = s.limits;
  const double angle =
      180.0 - std::acos(std::clamp(mirrors[0].normal.dot(mirrors[1].normal), -1.0, 1.0)) / kDeg;
  const bool angle_ok =
      angle >= limits.min_mirror_angle_deg && angle <= limits.max_mirror_angle_deg;
  result.checks.push_back(
      {"mirror_angle_deg", angle,
       Format("%g", limits.min_mirror_angle_deg) + ".." + Format("%g", limits.max_mirror_angle_deg),
       angle_ok});
  if (!angle_ok) {
    result.failures.push_back("the mirrors stand " + Format("%.2f", angle) +
                              "° apart, outside the plausible range; check the mirror mounts, "
                              "or the markers were misread");
  }
  for (int side = 0; side < 2; ++side) {
    const std::string name = side == 0 ? "left" : "right";
    const double tilt = std::asin(std::min(1.0, std::abs(mirrors[side].normal.z()))) / kDeg;
    const bool ok = tilt <= limits.max_mirror_tilt_deg;
    result.checks.push_back(
        {name + "_mirror_tilt_deg", tilt, "<= " + Format("%g", limits.max_mirror_tilt_deg), ok});
    if (!ok) {
      result.failures.push_back("the " + name + " mirror leans " + Format("%.2f", tilt) +
                                "° from vertical; is the target standing upright on the floor?");
    }
  }
  const auto corners = MirrorCorners(mirrors, s);
  const double corner_offset = (corners[0][0].head<2>() - s.corner_xy_mm).norm();
  const Eigen::Vector3d bisector = (mirrors[0].normal + mirrors[1].normal).normalized();
  const double yaw = std::atan2(bisector.x(), -bisector.y()) / kDeg;
  const bool corner_ok = corner_offset <= limits.max_corner_offset_mm;
  const bool yaw_ok = std::abs(yaw) <= limits.max_yaw_deg;
  result.checks.push_back({"corner_offset_mm", corner_offset,
                           "<= " + Format("%g", limits.max_corner_offset_mm), corner_ok});
  result.checks.push_back({"yaw_deg", yaw, "|x| <= " + Format("%g", limits.max_yaw_deg), yaw_ok});
  if (!corner_ok || !yaw_ok) {
    result.failures.push_back(
        "relative to the target the cabinet is " + Format("%.1f", corner_offset) +
        " mm off and turned " + Format("%.2f", yaw) +
        "°: the target is out of place; stand it on its floor mark, panel 0 square to the "
        "camera");
  }
}

void AddRmsChecks(const std::vector<CameraReport>& cameras, double limit, const char* what,
                  CalibrationResult& result) {
  for (const CameraReport& c : cameras) {
    for (const ViewReport& v : c.views) {
      if (v.found.empty()) continue;
      const double rms = v.rms_after_px;
      const bool ok = rms <= limit;
      result.checks.push_back(
          {c.name + "." + ViewName(v.view) + ".rms_px", rms, "<= " + Format("%g", limit), ok});
      if (!ok) {
        std::string why = v.view == ViewId::kCenter
                              ? "the camera or its lens moved, or the image is poor"
                              : std::string("the ") + ViewName(v.view) +
                                    " mirror moved, bends, or its view is disturbed";
        result.failures.push_back("camera " + c.name + ", " + ViewName(v.view) +
                                  " view: markers lie " + Format("%.3f", rms) + " px RMS " + what +
                                  " (limit " + Format("%g", limit) + "): " + why);
      }
    }
  }
}

}  // namespace mirrorscan::calibration::internal

#pragma once

// Laser height per frame (the paper's section 3.2): the laser lines on the diffuse panels
// behind the mirrors, where the camera sees the panels directly, give 3D points on known
// planes; a robust fit of height over time, presuming constant slide speed, gives every
// laser plane in every frame.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/config/calibration.h"
#include "common/geometry/camera.h"
#include "common/geometry/plane.h"
#include "common/scan_format/scan_format.h"

namespace mirrorscan {

// Too little on the panels to fit the lasers (no panel peaks, no line found).
class LaserHeightError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A planar rectangle: origin + a·along + b·up for a ∈ [0, width], b ∈ [0, height].
struct PlanarRectangle {
  std::string name;
  Plane plane;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d along = Eigen::Vector3d::UnitX();  // unit
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();     // unit, orthogonal to along
  double width = 0.0;
  double height = 0.0;

  // Where the ray meets the rectangle (ray parameter), nullopt if it misses it. Inline: the
  // reconstruction tries every panel and mirror on every ray segment.
  std::optional<double> Intersect(const Ray3d& ray) const {
    const auto t = IntersectRayPlane(ray, plane);
    if (!t) return std::nullopt;
    const Eigen::Vector3d local = ray.At(*t) - origin;
    const double a = local.dot(along), b = local.dot(up);
    if (a < 0 || a > width || b < 0 || b > height) return std::nullopt;
    return t;
  }
};

// The cabinet as the laser fit needs it: cameras by FrameRecord::camera, the mirror
// rectangles (a camera ray through one sees a reflection, not the panel behind it) and
// the panels behind them.
struct LaserCabinet {
  std::vector<Camera> cameras;
  std::vector<PlanarRectangle> mirrors;
  std::vector<PlanarRectangle> panels;
  std::vector<double> panel_offset_mm;  // per panel: how far behind its mirror it is taken to be
  int laser_count = 1;
  double nominal_spacing_mm = 200.0;  // laser k sits about k·spacing above laser 0
  double nominal_speed_mm_s = 0.0;    // 0: unknown, searched over (0, 1000] mm/s
};

// A panel parallel to its mirror, `panel_offset_mm` behind it, reaching `margin_mm`
// beyond the mirror's outer edge and top and down to the floor (z = 0), as the cabinet
// is built. `corners` as in calibration.json: inner bottom, outer bottom, outer top,
// inner top.
PlanarRectangle MirrorRectangle(const std::string& name, const Plane& mirror,
                                const std::array<Eigen::Vector3d, 4>& corners);
PlanarRectangle PanelBehindMirror(const PlanarRectangle& mirror, double panel_offset_mm,
                                  double margin_mm);

// The cabinet from calibration.json: cameras in the file's order, mirrors with their
// corners, panels as PanelBehindMirror builds them (the schema has no panel margin, so
// it is given), lasers from its "lasers" (count 1, nominal spacing and unknown speed
// without). ConfigError naming `file` when a mirror has no corners.
LaserCabinet LaserCabinetFromCalibration(const Calibration& calibration, const std::string& file,
                                         double panel_margin_mm = 120.0);

struct LaserHeightOptions {
  // Time origin of the fitted line, ns on the archive's clock (the header's start time).
  std::optional<int64_t> time_origin_ns;  // default: the first frame's timestamp
  // The slide readback is expected to be laser 0's height plus this offset.
  double readback_offset_mm = 0.0;
  double readback_tolerance_mm = 1.0;  // warn beyond this
  // A panel point further than this from every laser line is an outlier; the final gate
  // is the smaller of this and 5 robust sigmas (at least min_gate_mm).
  double gate_mm = 10.0;
  double min_gate_mm = 0.3;
  bool fit_tilt = true;
  // The laser planes' normal when it is known (the calibration's, measured over a whole
  // sweep): then fit_tilt is ignored. One scan's panel points, partly hidden by the subject,
  // fit a tilt that is a few hundredths of a degree off, ~0.1 mm across the cabinet.
  std::optional<Eigen::Vector3d> normal;
  // Fit how far each panel stands behind its mirror. Two cameras at different heights see
  // a wrong offset move the same line up in one and down in the other; one camera alone
  // cannot tell a common offset from a scale of the whole sweep, so a panel whose offset
  // is less certain than max_panel_offset_std_mm keeps the cabinet's.
  bool fit_panel_offsets = true;
  double max_panel_offset_std_mm = 0.1;
  // Threads for the per-peak and per-panel work (0: every core); the result is the same
  // for any number.
  int threads = 1;
};

// A peak whose camera ray meets a panel directly.
struct PanelPoint {
  size_t frame = 0;  // index into the archive's frames
  int panel = 0;
  uint16_t u = 0;
  float v = 0;
  Eigen::Vector3d point_in_world;  // on the panel at its fitted offset
  // How point_in_world moves along the ray per mm the panel stands further back.
  Eigen::Vector3d point_per_offset_mm = Eigen::Vector3d::Zero();
  int laser = -1;            // -1: an outlier (not on any laser line)
  double residual_mm = 0.0;  // signed distance to its laser plane (inliers)
};

// The lasers over the sweep: laser k at time t (s from time_origin_ns) is the plane
// normal · x = height_at_t0 + speed·t + offset[k], offset[0] = 0.
struct LaserFit {
  int64_t time_origin_ns = 0;
  double height_at_t0_mm = 0.0;
  double speed_mm_s = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  std::vector<double> offset_mm;  // per laser, relative to laser 0
  double spacing_mm = 0.0;        // mean step between neighbouring lasers

  // Rotation about x, then y, that turns +z into `normal`, as the scene's tilt_deg.
  Eigen::Vector2d TiltDeg() const;
  double TimeS(int64_t timestamp_ns) const { return (timestamp_ns - time_origin_ns) * 1e-9; }
  double HeightAt(int laser, double t) const {
    return height_at_t0_mm + speed_mm_s * t + offset_mm.at(laser);
  }
  Plane PlaneAt(int laser, double t) const { return Plane{normal, -HeightAt(laser, t)}; }
};

struct FrameLaserHeights {
  size_t frame = 0;  // index into the archive's frames
  uint8_t camera = 0;
  uint32_t sequence = 0;
  double time_s = 0.0;
  std::vector<double> height_mm;  // per laser, from the fitted line
  std::vector<int> panel_points;  // per laser, inlier points in this frame
  // Laser 0's height from this frame's points alone (NaN without any): what the line is
  // checked against.
  double measured_mm = std::numeric_limits<double>::quiet_NaN();
  double readback_mm = std::numeric_limits<double>::quiet_NaN();
};

struct ReadbackCheck {
  size_t frames = 0;          // frames with a readback
  double offset_mm = 0.0;     // median of readback − laser 0 height
  double max_error_mm = 0.0;  // max |readback − laser 0 height − expected offset|
  size_t frames_off = 0;      // beyond the tolerance
  size_t worst_frame = 0;
  double speed_mm_s = 0.0;  // slope of the readback over time
};

struct PanelOffset {
  std::string name;
  double assumed_mm = 0.0;  // the cabinet's (calibration.json)
  // assumed + fitted change; NaN when this scan cannot measure it (then assumed is used).
  double measured_mm = std::numeric_limits<double>::quiet_NaN();
  double std_error_mm = std::numeric_limits<double>::infinity();
  size_t inliers = 0;
  bool measured() const { return std::isfinite(measured_mm); }
  double used_mm() const { return measured() ? measured_mm : assumed_mm; }
  // Measured no further than `limit_mm` from the assumed offset; one not measured passes.
  bool WithinLimit(double limit_mm) const {
    return !measured() || std::abs(measured_mm - assumed_mm) <= limit_mm;
  }
};

struct LaserHeightResult {
  LaserFit fit;
  std::vector<PanelOffset> panel_offsets;  // per panel
  double residual_rms_mm = 0.0;            // inliers' distance to their laser plane
  double residual_max_mm = 0.0;
  double frame_rms_mm = 0.0;  // per-frame measured height against the line
  double frame_max_mm = 0.0;
  size_t candidates = 0;  // peaks whose ray meets a panel
  size_t inliers = 0;
  std::vector<size_t> inliers_per_laser;
  std::vector<PanelPoint> points;
  std::vector<FrameLaserHeights> frames;
  std::optional<ReadbackCheck> readback;
  std::vector<std::string> warnings;
};

// One line per panel measured out of place (beyond `limit_mm`), saying what to do.
std::vector<std::string> PanelOffsetFailures(const LaserHeightResult& result, double limit_mm);

// Throws LaserHeightError when there is too little on the panels to fit.
LaserHeightResult EstimateLaserHeights(const std::vector<FrameRecord>& frames,
                                       const LaserCabinet& cabinet,
                                       const LaserHeightOptions& options = {});

// Where a peak's camera ray meets a panel before any mirror: its panel point (laser not yet
// known); nullopt where it meets none first.
std::optional<PanelPoint> PanelPointOnRay(const LaserCabinet& cabinet, size_t frame, uint16_t u,
                                          float v, const Ray3d& ray);

// The same as EstimateLaserHeights from the panel points already found (PanelPointOnRay, in
// frame order), for a caller that has every peak's ray anyway: the frames give times,
// cameras and readbacks; their peaks are not read.
LaserHeightResult EstimateLaserHeightsFromPoints(const std::vector<FrameRecord>& frames,
                                                 const LaserCabinet& cabinet,
                                                 std::vector<PanelPoint> points,
                                                 const LaserHeightOptions& options = {});

}  // namespace mirrorscan

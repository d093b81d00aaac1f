#include "host/calibration/laser_height.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "common/parallel/parallel_for.h"

namespace mirrorscan {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
constexpr size_t kMinPanelPoints = 20;
// Camera centres closer than this count as one when deciding whether panel offsets can be
// measured.
constexpr double kMinCameraBaselineMm = 100.0;

std::string Format(const char* format, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), format, args...);
  return buffer;
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// Every peak whose camera ray meets a panel before any mirror.
}  // namespace

std::optional<PanelPoint> PanelPointOnRay(const LaserCabinet& cabinet, size_t frame, uint16_t u,
                                          float v, const Ray3d& ray) {
  double nearest = std::numeric_limits<double>::infinity();
  int panel = -1;
  for (size_t p = 0; p < cabinet.panels.size(); ++p) {
    if (const auto t = cabinet.panels[p].Intersect(ray); t && *t < nearest) {
      nearest = *t;
      panel = static_cast<int>(p);
    }
  }
  if (panel < 0) return std::nullopt;
  for (const PlanarRectangle& m : cabinet.mirrors)
    if (const auto t = m.Intersect(ray); t && *t < nearest) return std::nullopt;
  // The panel plane n·x + d = 0 moved δ further back is n·x + d + δ = 0: the ray meets it at
  // t − δ/(n·r).
  const Eigen::Vector3d per_offset =
      -ray.direction / cabinet.panels[panel].plane.normal.dot(ray.direction);
  return PanelPoint{frame, panel, u, v, ray.At(nearest), per_offset, -1, 0.0};
}

namespace {

void CheckInputs(const std::vector<FrameRecord>& frames, const LaserCabinet& cabinet) {
  if (cabinet.laser_count < 1) throw LaserHeightError("laser count must be at least 1");
  if (cabinet.panel_offset_mm.size() != cabinet.panels.size())
    throw LaserHeightError("the cabinet needs one panel offset per panel");
  if (frames.empty()) throw LaserHeightError("the scan has no frames");
}

// Frames in chunks on `threads`, each chunk's points in frame order, joined in chunk order.
std::vector<PanelPoint> CollectPanelPoints(const std::vector<FrameRecord>& frames,
                                           const LaserCabinet& cabinet, int threads) {
  for (size_t f = 0; f < frames.size(); ++f) {
    const FrameRecord& frame = frames[f];
    if (frame.lasers_on && frame.camera >= cabinet.cameras.size()) {
      throw LaserHeightError(Format("frame %zu (sequence %u): camera %d is not in the calibration",
                                    f, frame.sequence, frame.camera));
    }
  }
  std::vector<CameraRays> cameras;
  for (const Camera& camera : cabinet.cameras) cameras.push_back(camera.RaysThroughPixels());
  std::vector<std::vector<PanelPoint>> chunks(ChunkCount(frames.size(), threads));
  ForEachChunk(frames.size(), threads, [&](size_t c, size_t begin, size_t end) {
    std::vector<PanelPoint>& points = chunks[c];
    for (size_t f = begin; f < end; ++f) {
      const FrameRecord& frame = frames[f];
      if (!frame.lasers_on) continue;
      const CameraRays& camera = cameras[frame.camera];
      for (const Peak& peak : frame.peaks) {
        const auto ray = camera.Through({peak.u, peak.v});
        if (!ray) continue;
        if (auto point = PanelPointOnRay(cabinet, f, peak.u, peak.v, *ray))
          points.push_back(*point);
      }
    }
  });
  std::vector<PanelPoint> points;
  size_t total = 0;
  for (const auto& chunk : chunks) total += chunk.size();
  points.reserve(total);
  for (const auto& chunk : chunks) points.insert(points.end(), chunk.begin(), chunk.end());
  return points;
}

struct PanelLines {
  double speed = 0.0;
  std::vector<std::pair<double, int>> intercepts;  // (height at t = 0, laser), ascending
};

// The laser lines of one panel in the (time, height) plane, Hough-style: the slope whose
// intercepts z − v·t pile up sharpest, then the intercept histogram's strongest peaks
// (lasers numbered later, across panels).
PanelLines FindPanelLines(const std::vector<Eigen::Vector2d>& time_height,
                          const LaserCabinet& cabinet, double window_mm) {
  double t_min = std::numeric_limits<double>::infinity(), t_max = -t_min;
  for (const auto& p : time_height) {
    t_min = std::min(t_min, p.x());
    t_max = std::max(t_max, p.x());
  }
  const double span = t_max - t_min;
  if (!(span > 0)) throw LaserHeightError("all panel points come from one instant: no speed");
  // Coarse search on at most 20,000 points, then a fine one on all of them.
  const size_t stride = std::max<size_t>(1, time_height.size() / 20000);
  auto sharpness = [&](double speed, double bin, size_t step) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t i = 0; i < time_height.size(); i += step) {
      const double b = time_height[i].y() - speed * time_height[i].x();
      lo = std::min(lo, b);
      hi = std::max(hi, b);
    }
    std::vector<double> counts(static_cast<size_t>((hi - lo) / bin) + 1, 0.0);
    for (size_t i = 0; i < time_height.size(); i += step)
      counts[static_cast<size_t>((time_height[i].y() - speed * time_height[i].x() - lo) / bin)] +=
          1.0;
    return std::inner_product(counts.begin(), counts.end(), counts.begin(), 0.0);
  };
  auto best_speed = [&](double from, double to, double step, double bin, size_t point_step) {
    double best = from, best_score = -1.0;
    for (double v = from; v <= to; v += step) {
      const double s = sharpness(v, bin, point_step);
      if (s > best_score) {
        best_score = s;
        best = v;
      }
    }
    return best;
  };
  const double coarse_bin = 8.0;
  const double coarse_step = coarse_bin / span / 2.0;
  const double nominal = cabinet.nominal_speed_mm_s;
  const double from = nominal > 0 ? 0.7 * nominal : coarse_step;
  const double to = nominal > 0 ? 1.3 * nominal : 1000.0;
  double speed = best_speed(from, to, coarse_step, coarse_bin, stride);
  speed = best_speed(speed - coarse_step, speed + coarse_step, 0.5 / span, 2.0, 1);

  // Intercept histogram (1 mm bins), summed over a window that holds one tilted line.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& p : time_height) {
    lo = std::min(lo, p.y() - speed * p.x());
    hi = std::max(hi, p.y() - speed * p.x());
  }
  std::vector<double> counts(static_cast<size_t>(hi - lo) + 1, 0.0);
  for (const auto& p : time_height) counts[static_cast<size_t>(p.y() - speed * p.x() - lo)] += 1;
  const int half = static_cast<int>(std::ceil(window_mm));
  const int n = static_cast<int>(counts.size());
  std::vector<double> windowed(counts.size(), 0.0);
  for (int i = 0; i < n; ++i)
    for (int j = std::max(0, i - half); j <= std::min(n - 1, i + half); ++j)
      windowed[i] += counts[j];
  PanelLines lines;
  lines.speed = speed;
  const int suppress = static_cast<int>(cabinet.nominal_spacing_mm / 2);
  double strongest = 0.0;
  std::vector<double> found;
  for (int k = 0; k < cabinet.laser_count; ++k) {
    const int peak =
        static_cast<int>(std::max_element(windowed.begin(), windowed.end()) - windowed.begin());
    // Stripes on a subject in front of a panel pile up too, but far less than a laser
    // line that crosses the panel for much of the sweep.
    if (windowed[peak] <= 0 || windowed[peak] < 0.25 * strongest) break;
    strongest = std::max(strongest, windowed[peak]);
    double sum = 0, weight = 0;
    for (int j = std::max(0, peak - half); j <= std::min(n - 1, peak + half); ++j) {
      sum += counts[j] * (lo + j + 0.5);
      weight += counts[j];
    }
    found.push_back(sum / weight);
    for (int j = std::max(0, peak - suppress); j <= std::min(n - 1, peak + suppress); ++j)
      windowed[j] = 0;
  }
  std::sort(found.begin(), found.end());
  for (double b : found) lines.intercepts.emplace_back(b, -1);
  return lines;
}

// The joint model of step 2: z + a·x + b·y = h0 + v·t + c_k (c_0 = 0), the plane normal
// ∝ (a, b, 1), with each point moved along its ray by its panel's offset change δ_p where
// that is fitted.
struct JointFit {
  double a = 0, b = 0, h0 = 0, v = 0;
  std::vector<double> c;              // per laser
  std::vector<double> delta;          // per panel, mm further back than assumed
  std::vector<double> offset_std_mm;  // per panel; infinite where it cannot be measured
  bool tilt_dropped = false;          // lines on one panel only
};

// Unknowns of the normal equations: h0, v, c_k for each seen laser k > 0, then a, b,
// then δ_p for the panels whose offset is fitted.
struct Columns {
  std::vector<int> laser, offset;  // -1: not an unknown
  int tilt = -1;
  int count = 2;
};

Columns LayOutColumns(const std::vector<int>& seen, const std::vector<int>& panels_seen,
                      bool fit_tilt, const std::vector<bool>& fit_offset) {
  Columns columns;
  columns.laser.assign(seen.size(), -1);
  for (size_t k = 1; k < seen.size(); ++k)
    if (seen[k] > 0) columns.laser[k] = columns.count++;
  if (fit_tilt) {
    columns.tilt = columns.count;
    columns.count += 2;
  }
  columns.offset.assign(panels_seen.size(), -1);
  for (size_t p = 0; p < panels_seen.size(); ++p)
    if (fit_offset[p] && panels_seen[p] > 0) columns.offset[p] = columns.count++;
  return columns;
}

// The inliers' normal equations, linear in δ about the current tilt (a, b). A point's row
// has at most six non-zero entries, so only those products are summed (in point order, as
// a dense rank update would sum them: the same result, a fraction of the work).
void NormalEquations(const std::vector<PanelPoint>& points, const std::vector<double>& point_time,
                     const Columns& columns, double a, double b, Eigen::MatrixXd* normal_matrix,
                     Eigen::VectorXd* rhs) {
  *normal_matrix = Eigen::MatrixXd::Zero(columns.count, columns.count);
  *rhs = Eigen::VectorXd::Zero(columns.count);
  double* m = normal_matrix->data();  // column-major
  const Eigen::Index rows = normal_matrix->rows();
  for (size_t i = 0; i < points.size(); ++i) {
    const PanelPoint& p = points[i];
    if (p.laser < 0) continue;
    std::array<int, 6> column;
    std::array<double, 6> value;
    int n = 0;
    auto set = [&](int c, double v) {
      column[n] = c;
      value[n++] = v;
    };
    set(0, 1.0);
    set(1, point_time[i]);
    if (columns.laser[p.laser] >= 0) set(columns.laser[p.laser], 1.0);
    if (columns.tilt >= 0) {
      set(columns.tilt, -p.point_in_world.x());
      set(columns.tilt + 1, -p.point_in_world.y());
    }
    // z(δ) + a·x(δ) + b·y(δ) with x(δ) = x + w·δ.
    const Eigen::Vector3d& w = p.point_per_offset_mm;
    if (columns.offset[p.panel] >= 0)
      set(columns.offset[p.panel], -(w.z() + a * w.x() + b * w.y()));
    // The lower triangle.
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k)
        if (column[k] >= column[j]) m[column[j] * rows + column[k]] += value[j] * value[k];
    // A tilt that is not an unknown is a given one (0 unless LaserHeightOptions::normal).
    const Eigen::Vector3d& x = p.point_in_world;
    const double target = columns.tilt >= 0 ? x.z() : x.z() + a * x.x() + b * x.y();
    for (int j = 0; j < n; ++j) (*rhs)(column[j]) += value[j] * target;
  }
  normal_matrix->triangularView<Eigen::StrictlyUpper>() = normal_matrix->transpose();
}

// Fits the joint model, reassigning every candidate to its nearest laser plane under a
// gate that closes in to 5 robust sigmas; `points` keep their laser and residual.
JointFit FitJointly(std::vector<PanelPoint>& points, const std::vector<double>& point_time,
                    int lasers, double nominal_spacing_mm, const LaserHeightOptions& options,
                    const std::vector<bool>& fit_offset) {
  const int panels = static_cast<int>(fit_offset.size());
  JointFit fit;
  fit.c.assign(lasers, 0.0);
  fit.delta.assign(panels, 0.0);
  fit.offset_std_mm.assign(panels, std::numeric_limits<double>::infinity());
  double& a = fit.a;
  double& b = fit.b;
  double gate = options.gate_mm;
  bool fit_tilt = options.fit_tilt && !options.normal;
  if (options.normal) {
    a = options.normal->x() / options.normal->z();
    b = options.normal->y() / options.normal->z();
  }
  std::vector<int> seen(lasers, 0), panels_seen(panels, 0);
  auto moved = [&](const PanelPoint& p) -> Eigen::Vector3d {
    return p.point_in_world + p.point_per_offset_mm * fit.delta[p.panel];
  };
  Eigen::MatrixXd normal_matrix;
  Eigen::VectorXd rhs;
  Columns last_columns;
  const int threads = ResolveThreads(options.threads);
  for (int iteration = 0; iteration < 30; ++iteration) {
    std::fill(seen.begin(), seen.end(), 0);
    std::fill(panels_seen.begin(), panels_seen.end(), 0);
    for (const PanelPoint& p : points) {
      if (p.laser < 0) continue;
      ++seen[p.laser];
      ++panels_seen[p.panel];
    }
    if (fit_tilt &&
        std::count_if(panels_seen.begin(), panels_seen.end(), [](int n) { return n > 0; }) < 2) {
      fit_tilt = false;
      fit.tilt_dropped = true;
      a = b = 0;
    }
    const Columns columns = LayOutColumns(seen, panels_seen, fit_tilt, fit_offset);
    last_columns = columns;
    NormalEquations(points, point_time, columns, a, b, &normal_matrix, &rhs);
    const Eigen::VectorXd solution = normal_matrix.ldlt().solve(rhs);
    fit.h0 = solution(0);
    fit.v = solution(1);
    for (int k = 1; k < lasers; ++k)
      fit.c[k] = columns.laser[k] >= 0 ? solution(columns.laser[k]) : k * nominal_spacing_mm;
    if (fit_tilt) {
      a = solution(columns.tilt);
      b = solution(columns.tilt + 1);
    }
    double delta_change = 0;
    for (int p = 0; p < panels; ++p) {
      const double delta = columns.offset[p] >= 0 ? solution(columns.offset[p]) : 0.0;
      delta_change = std::max(delta_change, std::abs(delta - fit.delta[p]));
      fit.delta[p] = delta;
    }
    const double scale = std::sqrt(a * a + b * b + 1.0);
    auto lhs_of = [&](const PanelPoint& p, double t) {
      const Eigen::Vector3d x = moved(p);
      return (x.z() + a * x.x() + b * x.y() - fit.h0 - fit.v * t) / scale;
    };

    // Reassign every candidate to its nearest laser plane; gate at 5 robust sigmas.
    std::vector<double> abs_residual(points.size(), -1.0);
    ParallelFor(points.size(), threads, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const PanelPoint& p = points[i];
        if (p.laser >= 0)
          abs_residual[i] = std::abs(lhs_of(p, point_time[i]) - fit.c[p.laser] / scale);
      }
    });
    std::vector<double> inlier_abs;
    for (const double r : abs_residual)
      if (r >= 0) inlier_abs.push_back(r);
    const double sigma = 1.4826 * Median(inlier_abs);
    // The first pass keeps the wide gate, so a laser no panel showed as a line (placed at
    // the nominal spacing) can gather its points before the gate closes in.
    const double new_gate = iteration == 0
                                ? options.gate_mm
                                : std::clamp(5.0 * sigma, options.min_gate_mm, options.gate_mm);
    std::atomic<bool> changed{false};
    ParallelFor(points.size(), threads, [&](size_t begin, size_t end) {
      bool changed_here = false;
      for (size_t i = begin; i < end; ++i) {
        PanelPoint& p = points[i];
        const double lhs = lhs_of(p, point_time[i]);
        int best_laser = -1;
        double best = new_gate;
        for (int k = 0; k < lasers; ++k) {
          const double r = lhs - fit.c[k] / scale;
          if (std::abs(r) < best) {
            best = std::abs(r);
            best_laser = k;
            p.residual_mm = r;
          }
        }
        changed_here |= best_laser != p.laser;
        p.laser = best_laser;
      }
      if (changed_here) changed = true;
    });
    const bool converged =
        iteration > 0 && !changed && std::abs(new_gate - gate) < 1e-3 && delta_change < 1e-4;
    gate = new_gate;
    if (converged) break;
  }

  // Standard errors of the fitted offsets, from the last normal equations and the
  // inliers' residual RMS (unknowns scaled to a unit diagonal for a well-conditioned
  // inverse).
  double sum_sq = 0;
  size_t inliers = 0;
  for (const PanelPoint& p : points) {
    if (p.laser < 0) continue;
    sum_sq += p.residual_mm * p.residual_mm;
    ++inliers;
  }
  if (inliers == 0) return fit;
  const Eigen::VectorXd unit = normal_matrix.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd scaled = unit.asDiagonal() * normal_matrix * unit.asDiagonal();
  const Eigen::MatrixXd covariance =
      scaled.ldlt().solve(Eigen::MatrixXd::Identity(scaled.rows(), scaled.cols()));
  const double variance = sum_sq / static_cast<double>(inliers);
  for (int p = 0; p < panels; ++p) {
    const int col = last_columns.offset[p];
    if (col < 0) continue;
    const double std_error = unit(col) * std::sqrt(variance * covariance(col, col));
    if (std::isfinite(std_error)) fit.offset_std_mm[p] = std_error;
  }
  return fit;
}

}  // namespace

PlanarRectangle MirrorRectangle(const std::string& name, const Plane& mirror,
                                const std::array<Eigen::Vector3d, 4>& corners) {
  PlanarRectangle r;
  r.name = name;
  r.plane = mirror;
  r.origin = mirror.Project(corners[0]);
  const Eigen::Vector3d along = mirror.Project(corners[1]) - r.origin;
  const Eigen::Vector3d up = mirror.Project(corners[3]) - r.origin;
  r.width = along.norm();
  r.height = up.norm();
  r.along = along / r.width;
  r.up = (up - up.dot(r.along) * r.along).normalized();
  return r;
}

PlanarRectangle PanelBehindMirror(const PlanarRectangle& mirror, double panel_offset_mm,
                                  double margin_mm) {
  PlanarRectangle panel = mirror;
  panel.name = mirror.name + " panel";
  panel.plane.offset += panel_offset_mm;  // further from the subject
  const double floor_drop = mirror.origin.z() / mirror.up.z();
  panel.origin = mirror.origin - panel_offset_mm * mirror.plane.normal - floor_drop * mirror.up;
  panel.width = mirror.width + margin_mm;
  panel.height = floor_drop + mirror.height + margin_mm;
  return panel;
}

LaserCabinet LaserCabinetFromCalibration(const Calibration& calibration, const std::string& file,
                                         double panel_margin_mm) {
  LaserCabinet cabinet;
  for (const CalibrationCamera& camera : calibration.cameras)
    cabinet.cameras.push_back(camera.camera);
  for (size_t i = 0; i < calibration.mirrors.size(); ++i) {
    const CalibrationMirror& mirror = calibration.mirrors[i];
    if (mirror.corners_mm.size() != 4) {
      throw ConfigError(file + ": mirrors[" + std::to_string(i) +
                        "].corners_mm: the laser fit needs the mirror's 4 corners");
    }
    cabinet.mirrors.push_back(MirrorRectangle(
        mirror.name, mirror.plane,
        {mirror.corners_mm[0], mirror.corners_mm[1], mirror.corners_mm[2], mirror.corners_mm[3]}));
    cabinet.panels.push_back(
        PanelBehindMirror(cabinet.mirrors.back(), mirror.panel_offset_mm, panel_margin_mm));
    cabinet.panel_offset_mm.push_back(mirror.panel_offset_mm);
  }
  if (calibration.lasers) {
    cabinet.laser_count = calibration.lasers->count;
    cabinet.nominal_spacing_mm = calibration.lasers->spacing_mm;
    cabinet.nominal_speed_mm_s = calibration.lasers->speed_mm_s;
  }
  return cabinet;
}

std::vector<std::string> PanelOffsetFailures(const LaserHeightResult& result, double limit_mm) {
  std::vector<std::string> failures;
  for (const PanelOffset& offset : result.panel_offsets) {
    if (offset.WithinLimit(limit_mm)) continue;
    failures.push_back(Format(
        "%s: measured %.2f mm (± %.3f) behind its mirror, the calibration says %.2f mm "
        "(limit ± %g mm): check how the panel is mounted; if it is meant to stand there, set "
        "calibration.panel_offset_mm in board.json and calibrate again",
        offset.name.c_str(), offset.measured_mm, offset.std_error_mm, offset.assumed_mm, limit_mm));
  }
  return failures;
}

Eigen::Vector2d LaserFit::TiltDeg() const {
  return {std::atan2(-normal.y(), normal.z()) * kRadToDeg, std::asin(normal.x()) * kRadToDeg};
}

LaserHeightResult EstimateLaserHeights(const std::vector<FrameRecord>& frames,
                                       const LaserCabinet& cabinet,
                                       const LaserHeightOptions& options) {
  CheckInputs(frames, cabinet);
  return EstimateLaserHeightsFromPoints(
      frames, cabinet, CollectPanelPoints(frames, cabinet, ResolveThreads(options.threads)),
      options);
}

LaserHeightResult EstimateLaserHeightsFromPoints(const std::vector<FrameRecord>& frames,
                                                 const LaserCabinet& cabinet,
                                                 std::vector<PanelPoint> panel_points,
                                                 const LaserHeightOptions& options) {
  CheckInputs(frames, cabinet);
  const int threads = ResolveThreads(options.threads);
  LaserHeightResult result;
  LaserFit& fit = result.fit;
  fit.time_origin_ns = options.time_origin_ns.value_or(frames.front().timestamp_ns);
  result.points = std::move(panel_points);
  std::vector<PanelPoint>& points = result.points;
  result.candidates = points.size();
  if (points.size() < kMinPanelPoints) {
    throw LaserHeightError(
        Format("only %zu peaks lie on the panels beside the mirrors (need %zu): are the lasers on "
               "and the panels in view?",
               points.size(), kMinPanelPoints));
  }
  const int lasers = cabinet.laser_count;
  auto time_of = [&](const PanelPoint& p) { return fit.TimeS(frames[p.frame].timestamp_ns); };

  // 1. Lines per panel, numbered consistently across panels: in nominal spacings from the
  // lowest line any panel shows, which is taken to be laser 0.
  std::vector<PanelLines> panel_lines(cabinet.panels.size());
  double lowest = std::numeric_limits<double>::infinity();
  std::vector<std::vector<Eigen::Vector2d>> time_height(cabinet.panels.size());
  for (const PanelPoint& point : points)
    time_height[point.panel].emplace_back(time_of(point), point.point_in_world.z());
  // Panels on the threads, one at a time each.
  ForEachChunk(cabinet.panels.size(), threads, [&](size_t, size_t begin, size_t end) {
    for (size_t p = begin; p < end; ++p)
      if (time_height[p].size() >= kMinPanelPoints)
        panel_lines[p] = FindPanelLines(time_height[p], cabinet, 5.0);
  });
  for (size_t p = 0; p < cabinet.panels.size(); ++p) {
    if (time_height[p].size() < kMinPanelPoints) {
      if (!time_height[p].empty())
        result.warnings.push_back(Format("%s: only %zu points, not used",
                                         cabinet.panels[p].name.c_str(), time_height[p].size()));
      continue;
    }
    if (!panel_lines[p].intercepts.empty())
      lowest = std::min(lowest, panel_lines[p].intercepts.front().first);
  }
  if (!std::isfinite(lowest))
    throw LaserHeightError("no panel has enough laser points to fit a line");
  for (PanelLines& lines : panel_lines) {
    for (auto& [intercept, laser] : lines.intercepts)
      laser = static_cast<int>(std::lround((intercept - lowest) / cabinet.nominal_spacing_mm));
  }
  for (size_t p = 0; p < cabinet.panels.size(); ++p) {
    const PanelLines& lines = panel_lines[p];
    if (lines.intercepts.empty()) continue;
    if (static_cast<int>(lines.intercepts.size()) < lasers)
      result.warnings.push_back(Format("%s: %zu of %d laser lines found",
                                       cabinet.panels[p].name.c_str(), lines.intercepts.size(),
                                       lasers));
    for (const auto& [intercept, laser] : lines.intercepts) {
      if (laser >= lasers)
        throw LaserHeightError(Format(
            "%s: a laser line at %.1f mm (t = 0) is %.0f spacings from the lowest line: "
            "laser spacing %.1f mm or laser count %d wrong?",
            cabinet.panels[p].name.c_str(), intercept,
            (intercept - lowest) / cabinet.nominal_spacing_mm, cabinet.nominal_spacing_mm, lasers));
    }
  }
  for (PanelPoint& point : points) {
    const PanelLines& lines = panel_lines[point.panel];
    double best = options.gate_mm;
    point.laser = -1;
    for (const auto& [intercept, laser] : lines.intercepts) {
      const double r =
          std::abs(point.point_in_world.z() - intercept - lines.speed * time_of(point));
      if (r < best) {
        best = r;
        point.laser = laser;
      }
    }
  }

  // 2. One model for all panels and lasers, refit with a shrinking gate; the panels'
  // offsets are fitted where this scan can measure them, else kept as the cabinet's.
  std::vector<double> point_time(points.size());
  for (size_t i = 0; i < points.size(); ++i) point_time[i] = time_of(points[i]);
  const int panels = static_cast<int>(cabinet.panels.size());
  // First with the cabinet's offsets. Then the offsets free, if two camera centres see
  // the panels: moving a panel back scales the points one camera sees on it about that
  // camera, which a line fit cannot tell from the sweep's own scale (and would shrink to
  // nothing), while a second camera sees the same lines scaled about another centre.
  const std::vector<bool> none(panels, false);
  JointFit joint =
      FitJointly(points, point_time, lasers, cabinet.nominal_spacing_mm, options, none);
  std::vector<bool> camera_used(cabinet.cameras.size(), false);
  for (const PanelPoint& p : points)
    if (p.laser >= 0) camera_used[frames[p.frame].camera] = true;
  std::vector<Eigen::Vector3d> centres;
  for (size_t i = 0; i < cabinet.cameras.size(); ++i) {
    if (!camera_used[i]) continue;
    const Eigen::Vector3d centre = cabinet.cameras[i].CenterInWorld();
    if (std::none_of(centres.begin(), centres.end(), [&](const Eigen::Vector3d& c) {
          return (c - centre).norm() < kMinCameraBaselineMm;
        }))
      centres.push_back(centre);
  }
  std::vector<bool> free_offset(panels, options.fit_panel_offsets && centres.size() >= 2);
  if (std::find(free_offset.begin(), free_offset.end(), true) != free_offset.end()) {
    joint =
        FitJointly(points, point_time, lasers, cabinet.nominal_spacing_mm, options, free_offset);
    // A panel only glimpsed gives too uncertain an offset: keep the cabinet's.
    bool uncertain = false;
    for (int p = 0; p < panels; ++p) {
      if (free_offset[p] && !(joint.offset_std_mm[p] <= options.max_panel_offset_std_mm)) {
        free_offset[p] = false;
        uncertain = true;
      }
    }
    if (uncertain) {
      const std::vector<double> offset_std = joint.offset_std_mm;
      joint =
          FitJointly(points, point_time, lasers, cabinet.nominal_spacing_mm, options, free_offset);
      for (int p = 0; p < panels; ++p)
        if (!free_offset[p]) joint.offset_std_mm[p] = offset_std[p];
    }
  }
  if (joint.tilt_dropped)
    result.warnings.push_back("laser lines on one panel only: tilt not fitted (assumed level)");
  const double a = joint.a, b = joint.b, h0 = joint.h0, v = joint.v;
  const std::vector<double>& c = joint.c;
  for (PanelPoint& p : points) p.point_in_world += p.point_per_offset_mm * joint.delta[p.panel];
  std::vector<size_t> panel_inliers(panels, 0);
  for (const PanelPoint& p : points)
    if (p.laser >= 0) ++panel_inliers[p.panel];
  std::vector<std::string> unmeasured;
  for (int p = 0; p < panels; ++p) {
    PanelOffset offset;
    offset.name = cabinet.panels[p].name;
    offset.assumed_mm = cabinet.panel_offset_mm[p];
    offset.std_error_mm = joint.offset_std_mm[p];
    offset.inliers = panel_inliers[p];
    if (free_offset[p]) offset.measured_mm = offset.assumed_mm + joint.delta[p];
    if (options.fit_panel_offsets && !free_offset[p] && panel_inliers[p] > 0)
      unmeasured.push_back(offset.name);
    result.panel_offsets.push_back(offset);
  }
  if (!unmeasured.empty()) {
    std::string names;
    for (const std::string& name : unmeasured) names += (names.empty() ? "" : ", ") + name;
    result.warnings.push_back(
        "panel offset not measured from this scan (" + names + "): " +
        (centres.size() < 2
             ? "one camera cannot tell it from the sweep's scale, two cameras can"
             : Format("its standard error exceeds %.2f mm", options.max_panel_offset_std_mm)) +
        "; the calibration's is used");
  }

  const double scale = std::sqrt(a * a + b * b + 1.0);
  fit.normal = Eigen::Vector3d(a, b, 1.0) / scale;
  fit.height_at_t0_mm = h0 / scale;
  fit.speed_mm_s = v / scale;
  fit.offset_mm.assign(lasers, 0.0);
  for (int k = 1; k < lasers; ++k) fit.offset_mm[k] = c[k] / scale;
  fit.spacing_mm = lasers > 1 ? fit.offset_mm.back() / (lasers - 1) : 0.0;

  // 3. Per frame: the fitted heights, and laser 0's height measured from the frame alone.
  result.inliers_per_laser.assign(lasers, 0);
  double sum_sq = 0;
  std::vector<double> frame_sum(frames.size(), 0.0);
  std::vector<std::vector<int>> frame_count(frames.size(), std::vector<int>(lasers, 0));
  for (const PanelPoint& p : points) {
    if (p.laser < 0) continue;
    ++result.inliers;
    ++result.inliers_per_laser[p.laser];
    sum_sq += p.residual_mm * p.residual_mm;
    result.residual_max_mm = std::max(result.residual_max_mm, std::abs(p.residual_mm));
    const Eigen::Vector3d& x = p.point_in_world;
    frame_sum[p.frame] += fit.normal.dot(x) - fit.offset_mm[p.laser];
    ++frame_count[p.frame][p.laser];
  }
  if (result.inliers == 0) throw LaserHeightError("no panel point lies on a fitted laser line");
  for (int k = 0; k < lasers; ++k) {
    if (result.inliers_per_laser[k] == 0)
      result.warnings.push_back(
          Format("laser %d: never seen on the panels; placed at the nominal spacing", k));
  }
  result.residual_rms_mm = std::sqrt(sum_sq / result.inliers);

  double frame_sq = 0;
  size_t frames_measured = 0;
  std::vector<double> readback_errors;
  std::vector<Eigen::Vector2d> readback_points;  // (time, readback)
  for (size_t f = 0; f < frames.size(); ++f) {
    const FrameRecord& record = frames[f];
    FrameLaserHeights heights;
    heights.frame = f;
    heights.camera = record.camera;
    heights.sequence = record.sequence;
    heights.time_s = fit.TimeS(record.timestamp_ns);
    for (int k = 0; k < lasers; ++k) heights.height_mm.push_back(fit.HeightAt(k, heights.time_s));
    heights.panel_points = frame_count[f];
    const int count = std::accumulate(frame_count[f].begin(), frame_count[f].end(), 0);
    if (count > 0) {
      heights.measured_mm = frame_sum[f] / count;
      const double error = heights.measured_mm - heights.height_mm[0];
      frame_sq += error * error;
      result.frame_max_mm = std::max(result.frame_max_mm, std::abs(error));
      ++frames_measured;
    }
    heights.readback_mm = record.slide_position_mm;
    if (std::isfinite(record.slide_position_mm)) {
      readback_errors.push_back(record.slide_position_mm - heights.height_mm[0]);
      readback_points.emplace_back(heights.time_s, record.slide_position_mm);
    }
    result.frames.push_back(std::move(heights));
  }
  if (frames_measured > 0) result.frame_rms_mm = std::sqrt(frame_sq / frames_measured);

  // 4. The drive's readback against the line.
  if (!readback_errors.empty()) {
    ReadbackCheck check;
    check.frames = readback_errors.size();
    check.offset_mm = Median(readback_errors);
    size_t i = 0;
    for (const FrameLaserHeights& heights : result.frames) {
      if (!std::isfinite(heights.readback_mm)) continue;
      const double error = std::abs(readback_errors[i++] - options.readback_offset_mm);
      if (error > options.readback_tolerance_mm) ++check.frames_off;
      if (error > check.max_error_mm) {
        check.max_error_mm = error;
        check.worst_frame = heights.frame;
      }
    }
    if (readback_points.size() >= 2) {
      Eigen::MatrixXd design(readback_points.size(), 2);
      Eigen::VectorXd values(readback_points.size());
      for (size_t j = 0; j < readback_points.size(); ++j) {
        design.row(j) << 1.0, readback_points[j].x();
        values(j) = readback_points[j].y();
      }
      check.speed_mm_s = design.colPivHouseholderQr().solve(values)(1);
    }
    if (check.frames_off > 0) {
      result.warnings.push_back(Format(
          "slide readback disagrees with the laser lines on the panels: %zu of %zu frames off "
          "by more than %.2f mm (worst %.2f mm at frame %zu; median readback − laser 0 = "
          "%.2f mm, expected %.2f mm; readback speed %.3f mm/s, lines %.3f mm/s)",
          check.frames_off, check.frames, options.readback_tolerance_mm, check.max_error_mm,
          check.worst_frame, check.offset_mm, options.readback_offset_mm, check.speed_mm_s,
          fit.speed_mm_s));
      // A whole number of spacings: most likely laser 0 never reached a panel, so the
      // lowest line seen was numbered 0.
      const double spacings =
          (check.offset_mm - options.readback_offset_mm) / cabinet.nominal_spacing_mm;
      if (lasers > 1 && std::abs(spacings) > 0.5 &&
          std::abs(spacings - std::round(spacings)) < 0.05) {
        result.warnings.back() += Format(
            "; that is %.0f laser spacing(s): was the lowest laser never on the panels?", spacings);
      }
    }
    result.readback = check;
  }
  return result;
}

}  // namespace mirrorscan

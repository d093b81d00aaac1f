#include "host/calibration/calibrate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

namespace mirrorscan::calibration {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

// A point found on a marker's edge: the edge runs from a to b on the target, the point
// lies at about a + t (b - a).
struct EdgePoint {
  Eigen::Vector3d a, b;
  double t = 0.0;
  Eigen::Vector2d pixel;
};

// Every corner of one view: where the target has it and where the image shows it.
struct ViewPoints {
  std::vector<Eigen::Vector3d> in_world;
  std::vector<Eigen::Vector2d> in_panel;  // (right, up) in mm on its panel
  std::vector<Eigen::Vector2d> pixels;
  std::vector<EdgePoint> edges;
};

struct CameraData {
  std::string name;
  int width = 0, height = 0;
  std::optional<CameraIntrinsics> lens;  // fixed, from a lens calibration
  std::array<ViewPoints, kViews> views;
  CameraReport report;
};

MarkerDetectorOptions DetectorOptions(const CalibrationTarget& target) {
  MarkerDetectorOptions options;
  options.markers_per_panel = kTargetMarkersPerPanel;
  for (const auto& m : target.markers()) {
    std::array<Eigen::Vector2d, 4> layout;
    for (int c = 0; c < 4; ++c) layout[c] = target.PanelCoordinates(m.panel, m.corners[c]);
    options.layout_mm.push_back(layout);
  }
  return options;
}

CameraData Detect(const CameraImage& image, const CalibrationTarget& target) {
  if (image.gray.empty() || image.gray.type() != CV_8UC1) {
    throw std::invalid_argument("camera " + image.name + ": expected an 8-bit grayscale image");
  }
  CameraData data;
  data.name = image.name;
  data.width = image.gray.cols;
  data.height = image.gray.rows;
  data.report.name = image.name;
  if (image.lens) {
    if (image.lens->width != data.width || image.lens->height != data.height) {
      throw std::invalid_argument("camera " + image.name + ": the lens calibration is for " +
                                  std::to_string(image.lens->width) + "x" +
                                  std::to_string(image.lens->height) + " images, this image is " +
                                  std::to_string(data.width) + "x" + std::to_string(data.height));
    }
    data.lens = image.lens;
  }
  const auto detections = DetectTargetMarkers(image.gray, DetectorOptions(target));
  std::vector<uint8_t> levels(image.gray.begin<uint8_t>(), image.gray.end<uint8_t>());
  std::nth_element(levels.begin(), levels.begin() + levels.size() * 99 / 100, levels.end());
  data.report.white_dn = levels[levels.size() * 99 / 100];
  for (int v = 0; v < kViews; ++v) {
    ViewReport& report = data.report.views[v];
    report.view = static_cast<ViewId>(v);
    report.rejected = detections[v].rejected;
    ViewPoints& points = data.views[v];
    std::vector<bool> seen(kTargetMarkersPerPanel, false);
    for (const DetectedMarker& m : detections[v].markers) {
      const auto& truth = target.markers()[m.id];
      report.found.push_back(m.id);
      seen[m.id % kTargetMarkersPerPanel] = true;
      report.contrast_dn += m.contrast_dn / detections[v].markers.size();
      report.edge_sigma_px += m.edge_sigma_px / detections[v].markers.size();
      for (int c = 0; c < 4; ++c) {
        points.in_world.push_back(truth.corners[c]);
        points.in_panel.push_back(target.PanelCoordinates(v, truth.corners[c]));
        points.pixels.push_back(m.corners[c]);
        const Eigen::Vector2d from = m.corners[c], to = m.corners[(c + 1) % 4];
        for (const Eigen::Vector2d& p : m.edge_points[c]) {
          points.edges.push_back({truth.corners[c], truth.corners[(c + 1) % 4],
                                  (p - from).dot(to - from) / (to - from).squaredNorm(), p});
        }
      }
    }
    for (int i = 0; i < kTargetMarkersPerPanel; ++i) {
      if (!seen[i]) report.missing.push_back(v * kTargetMarkersPerPanel + i);
    }
    report.observed = points.pixels;
  }
  std::vector<Eigen::Vector2d> support =
      image.lens ? image.lens_support_px : std::vector<Eigen::Vector2d>{};
  for (const ViewPoints& v : data.views)
    support.insert(support.end(), v.pixels.begin(), v.pixels.end());
  data.report.coverage = LensCoverage::Of(support, data.width, data.height);
  data.report.coverage.lens_fixed = image.lens.has_value();
  return data;
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

// ---- Steps 1 and 2: three camera models per camera, mirrors by Eq. 1 ----

// Pose of the (virtual, for mirror views flipped) camera of one view for given
// intrinsics, from the view's planar panel.
Rigid3d ViewPose(const CameraData& data, int view, const CameraIntrinsics& k,
                 const CalibrationTarget& target) {
  std::vector<cv::Point3d> object_points;
  std::vector<cv::Point2d> image_points;
  const ViewPoints& points = data.views[view];
  for (size_t i = 0; i < points.pixels.size(); ++i) {
    object_points.emplace_back(points.in_panel[i].x(), points.in_panel[i].y(), 0.0);
    const double u = view == 0 ? points.pixels[i].x() : data.width - 1 - points.pixels[i].x();
    image_points.emplace_back(u, points.pixels[i].y());
  }
  // The flipped image of a mirror view is an ordinary camera with cx -> width - 1 - cx and,
  // since x -> -x, p2 -> -p2.
  const cv::Matx33d camera_matrix(k.fx, 0, view == 0 ? k.cx : data.width - 1 - k.cx, 0, k.fy, k.cy,
                                  0, 0, 1);
  const cv::Vec<double, 5> distortion(k.k1, k.k2, k.p1, view == 0 ? k.p2 : -k.p2, k.k3);
  cv::Mat rvec, tvec;
  cv::solvePnP(object_points, image_points, camera_matrix, distortion, rvec, tvec);
  cv::Mat rotation;
  cv::Rodrigues(rvec, rotation);
  Eigen::Matrix3d cam_from_panel;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, cam_from_panel);
  cv::cv2eigen(tvec, t);
  const auto& panel = target.panels()[view];
  Eigen::Matrix3d panel_from_world;
  panel_from_world.row(0) = panel.right.transpose();
  panel_from_world.row(1) = panel.up.transpose();
  panel_from_world.row(2) = panel.normal.transpose();
  const Eigen::Matrix3d r = cam_from_panel * panel_from_world;
  return Rigid3d(Eigen::Quaterniond(r), t - r * panel.origin);
}

struct InitialModel {
  Camera camera;                 // the real camera (centre view)
  std::array<Plane, 2> mirrors;  // Eq. 1 from the reflected focal points
  double rms_px = 0.0;           // of this one model over all three views
};

InitialModel ModelForIntrinsics(const CameraData& data, const CameraIntrinsics& k,
                                const CalibrationTarget& target) {
  InitialModel model;
  model.camera = {k, ViewPose(data, 0, k, target)};
  const Eigen::Vector3d centre = model.camera.CenterInWorld();
  double sum2 = 0.0;
  size_t n = 0;
  for (int side = 0; side < 2; ++side) {
    const Eigen::Vector3d reflected = ViewPose(data, side + 1, k, target).Inverse().translation;
    model.mirrors[side] = Plane::Bisector(centre, reflected);
  }
  for (int v = 0; v < kViews; ++v) {
    const ViewPoints& points = data.views[v];
    for (size_t i = 0; i < points.pixels.size(); ++i) {
      const auto p = v == 0
                         ? model.camera.ProjectWorld(points.in_world[i])
                         : model.camera.ProjectViaMirror(points.in_world[i], model.mirrors[v - 1]);
      sum2 += p ? (*p - points.pixels[i]).squaredNorm() : 1e6;
      ++n;
    }
  }
  model.rms_px = std::sqrt(sum2 / n);
  return model;
}

// Steps 1 and 2. Each view sees one planar panel, and by the cabinet's symmetry all three
// see theirs from much the same angle, so no view, nor Zhang's method over the three,
// pins the focal length (it lands far off). What does pin it is the cabinet: only with
// the right focal length do the three per-view models (the centre camera and the two
// reflected, x-mirrored ones, posed from their panels by PnP) agree with one camera and
// two mirrors at the mid-planes of Eq. 1. So the focal length is the one whose combined
// model reprojects best, searched over a wide range with the principal point at the
// image centre and no distortion; the joint refinement frees everything.
InitialModel InitialiseModel(const CameraData& data, const CalibrationTarget& target) {
  if (data.lens) return ModelForIntrinsics(data, *data.lens, target);
  CameraIntrinsics k;
  k.width = data.width;
  k.height = data.height;
  k.cx = (data.width - 1) / 2.0;
  k.cy = (data.height - 1) / 2.0;
  auto model_for = [&](double f) {
    k.fx = k.fy = f;
    return ModelForIntrinsics(data, k, target);
  };
  double best_f = 0.0;
  InitialModel best;
  best.rms_px = std::numeric_limits<double>::infinity();
  for (double f = 0.3 * data.width; f <= 6.0 * data.width; f *= 1.02) {
    const InitialModel m = model_for(f);
    if (m.rms_px < best.rms_px) best = m, best_f = f;
  }
  for (double f = best_f / 1.02; f <= best_f * 1.02; f *= 1.001) {
    const InitialModel m = model_for(f);
    if (m.rms_px < best.rms_px) best = m;
  }
  return best;
}

// ---- Step 3: joint refinement ----

template <typename T>
void ProjectPoint(const T* intrinsics, const T* rotation, const T* translation,
                  const Eigen::Matrix<T, 3, 1>& point, T* pixel) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(rotation);
  const Eigen::Matrix<T, 3, 1> p =
      q * point + Eigen::Map<const Eigen::Matrix<T, 3, 1>>(translation);
  const T x = p.x() / p.z(), y = p.y() / p.z();
  const T& k1 = intrinsics[4];
  const T& k2 = intrinsics[5];
  const T& p1 = intrinsics[6];
  const T& p2 = intrinsics[7];
  const T& k3 = intrinsics[8];
  const T r2 = x * x + y * y;
  const T radial = T(1) + r2 * (k1 + r2 * (k2 + r2 * k3));
  const T xd = x * radial + T(2) * p1 * x * y + p2 * (r2 + T(2) * x * x);
  const T yd = y * radial + p1 * (r2 + T(2) * y * y) + T(2) * p2 * x * y;
  pixel[0] = intrinsics[0] * xd + intrinsics[2];
  pixel[1] = intrinsics[1] * yd + intrinsics[3];
}

struct DirectResidual {
  Eigen::Vector3d point;
  Eigen::Vector2d pixel;
  template <typename T>
  bool operator()(const T* intrinsics, const T* rotation, const T* translation, T* residual) const {
    T projected[2];
    ProjectPoint(intrinsics, rotation, translation, point.cast<T>().eval(), projected);
    residual[0] = projected[0] - T(pixel.x());
    residual[1] = projected[1] - T(pixel.y());
    return true;
  }
};

// A point seen in a mirror projects as its reflection (DESIGN.md); the normal is kept
// unit by its manifold.
struct MirrorResidual {
  Eigen::Vector3d point;
  Eigen::Vector2d pixel;
  template <typename T>
  bool operator()(const T* intrinsics, const T* rotation, const T* translation, const T* normal,
                  const T* offset, T* residual) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> n(normal);
    const Eigen::Matrix<T, 3, 1> p = point.cast<T>();
    const Eigen::Matrix<T, 3, 1> reflected = p - T(2) * (n.dot(p) + offset[0]) * n;
    T projected[2];
    ProjectPoint(intrinsics, rotation, translation, reflected, projected);
    residual[0] = projected[0] - T(pixel.x());
    residual[1] = projected[1] - T(pixel.y());
    return true;
  }
};

// Distance of an edge point from the projected edge, along the edge's image normal: the
// projected point at the same place along the edge slides along it freely.
template <typename T>
T EdgeDistance(const T* intrinsics, const T* rotation, const T* translation,
               const Eigen::Matrix<T, 3, 1>& a, const Eigen::Matrix<T, 3, 1>& b, double t,
               const Eigen::Vector2d& pixel) {
  T pa[2], pb[2], pt[2];
  ProjectPoint(intrinsics, rotation, translation, a, pa);
  ProjectPoint(intrinsics, rotation, translation, b, pb);
  ProjectPoint(intrinsics, rotation, translation, (a + T(t) * (b - a)).eval(), pt);
  const T dx = pb[0] - pa[0], dy = pb[1] - pa[1];
  const T length = ceres::sqrt(dx * dx + dy * dy);
  return (-dy * (pt[0] - T(pixel.x())) + dx * (pt[1] - T(pixel.y()))) / length;
}

struct DirectEdgeResidual {
  EdgePoint edge;
  template <typename T>
  bool operator()(const T* intrinsics, const T* rotation, const T* translation, T* residual) const {
    residual[0] = EdgeDistance(intrinsics, rotation, translation, edge.a.cast<T>().eval(),
                               edge.b.cast<T>().eval(), edge.t, edge.pixel);
    return true;
  }
};

struct MirrorEdgeResidual {
  EdgePoint edge;
  template <typename T>
  bool operator()(const T* intrinsics, const T* rotation, const T* translation, const T* normal,
                  const T* offset, T* residual) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> n(normal);
    auto reflect = [&](const Eigen::Vector3d& point) {
      const Eigen::Matrix<T, 3, 1> p = point.cast<T>();
      return (p - T(2) * (n.dot(p) + offset[0]) * n).eval();
    };
    residual[0] = EdgeDistance(intrinsics, rotation, translation, reflect(edge.a), reflect(edge.b),
                               edge.t, edge.pixel);
    return true;
  }
};

struct CameraParameters {
  std::array<double, 9> intrinsics;
  std::array<double, 4> rotation;  // Eigen order x, y, z, w
  std::array<double, 3> translation;

  static CameraParameters From(const Camera& camera) {
    const CameraIntrinsics& k = camera.intrinsics;
    CameraParameters p;
    p.intrinsics = {k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2, k.k3};
    const Eigen::Quaterniond& q = camera.cam_from_world.rotation;
    p.rotation = {q.x(), q.y(), q.z(), q.w()};
    p.translation = {camera.cam_from_world.translation.x(), camera.cam_from_world.translation.y(),
                     camera.cam_from_world.translation.z()};
    return p;
  }
  Camera ToCamera(int width, int height) const {
    Camera c;
    CameraIntrinsics& k = c.intrinsics;
    k.width = width;
    k.height = height;
    k.fx = intrinsics[0], k.fy = intrinsics[1], k.cx = intrinsics[2], k.cy = intrinsics[3];
    k.k1 = intrinsics[4], k.k2 = intrinsics[5], k.p1 = intrinsics[6], k.p2 = intrinsics[7];
    k.k3 = intrinsics[8];
    c.cam_from_world =
        Rigid3d(Eigen::Quaterniond(rotation[3], rotation[0], rotation[1], rotation[2]),
                {translation[0], translation[1], translation[2]});
    return c;
  }
};

struct MirrorParameters {
  std::array<double, 3> normal;
  double offset = 0.0;
};

// False when the solver gives up with nothing usable.
bool Refine(const std::vector<CameraData>& data, std::vector<CameraParameters>& cameras,
            std::array<MirrorParameters, 2>& mirrors) {
  ceres::Problem problem;
  for (size_t c = 0; c < data.size(); ++c) {
    CameraParameters& p = cameras[c];
    for (int v = 0; v < kViews; ++v) {
      const ViewPoints& points = data[c].views[v];
      for (const EdgePoint& edge : points.edges) {
        auto* loss = new ceres::HuberLoss(1.0);
        if (v == 0) {
          problem.AddResidualBlock(new ceres::AutoDiffCostFunction<DirectEdgeResidual, 1, 9, 4, 3>(
                                       new DirectEdgeResidual{edge}),
                                   loss, p.intrinsics.data(), p.rotation.data(),
                                   p.translation.data());
        } else {
          MirrorParameters& m = mirrors[v - 1];
          problem.AddResidualBlock(
              new ceres::AutoDiffCostFunction<MirrorEdgeResidual, 1, 9, 4, 3, 3, 1>(
                  new MirrorEdgeResidual{edge}),
              loss, p.intrinsics.data(), p.rotation.data(), p.translation.data(), m.normal.data(),
              &m.offset);
        }
      }
      // The corners too: they tie the edges' ends together.
      for (size_t i = 0; i < points.pixels.size(); ++i) {
        auto* loss = new ceres::HuberLoss(1.0);
        if (v == 0) {
          problem.AddResidualBlock(new ceres::AutoDiffCostFunction<DirectResidual, 2, 9, 4, 3>(
                                       new DirectResidual{points.in_world[i], points.pixels[i]}),
                                   loss, p.intrinsics.data(), p.rotation.data(),
                                   p.translation.data());
        } else {
          MirrorParameters& m = mirrors[v - 1];
          problem.AddResidualBlock(
              new ceres::AutoDiffCostFunction<MirrorResidual, 2, 9, 4, 3, 3, 1>(
                  new MirrorResidual{points.in_world[i], points.pixels[i]}),
              loss, p.intrinsics.data(), p.rotation.data(), p.translation.data(), m.normal.data(),
              &m.offset);
        }
      }
    }
    problem.SetManifold(p.rotation.data(), new ceres::EigenQuaternionManifold);
    if (data[c].lens) problem.SetParameterBlockConstant(p.intrinsics.data());
  }
  for (auto& m : mirrors) problem.SetManifold(m.normal.data(), new ceres::SphereManifold<3>);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-14;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return summary.IsSolutionUsable();
}

// ---- Residuals, checks, output ----

std::optional<Eigen::Vector2d> ProjectInView(const Camera& camera, const Plane* mirror,
                                             const Eigen::Vector3d& point) {
  return mirror ? camera.ProjectViaMirror(point, *mirror) : camera.ProjectWorld(point);
}

struct Rms {
  double rms = 0.0, max = 0.0;
  std::vector<Eigen::Vector2d> reprojected;
};

Rms Residuals(const Camera& camera, const Plane* mirror, const ViewPoints& points) {
  Rms r;
  double sum2 = 0.0;
  for (size_t i = 0; i < points.pixels.size(); ++i) {
    const auto p = ProjectInView(camera, mirror, points.in_world[i]);
    // A point the model cannot project counts as far off.
    const Eigen::Vector2d projected = p ? *p : points.pixels[i] + Eigen::Vector2d(1e3, 0.0);
    const double e = (projected - points.pixels[i]).norm();
    sum2 += e * e;
    r.max = std::max(r.max, e);
    r.reprojected.push_back(projected);
  }
  if (!points.pixels.empty()) r.rms = std::sqrt(sum2 / points.pixels.size());
  return r;
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

std::vector<CameraData> DetectAll(const std::vector<CameraImage>& images,
                                  const CalibrationSettings& settings,
                                  const CalibrationTarget& target, CalibrationResult& result,
                                  bool& solvable) {
  if (images.empty()) throw std::invalid_argument("no camera image given");
  std::vector<CameraData> data;
  solvable = true;
  for (const CameraImage& image : images) {
    if (std::find(settings.camera_names.begin(), settings.camera_names.end(), image.name) ==
        settings.camera_names.end()) {
      throw std::invalid_argument("camera \"" + image.name + "\" is not in the board's cameras");
    }
    data.push_back(Detect(image, target));
    solvable = CheckDetections(data.back(), settings.limits, result) && solvable;
    result.cameras.push_back(data.back().report);
  }
  return data;
}

}  // namespace

LensCoverage LensCoverage::Of(const std::vector<Eigen::Vector2d>& pixels, int width, int height) {
  LensCoverage coverage;
  for (const Eigen::Vector2d& p : pixels) {
    const int column = static_cast<int>(std::floor((p.x() + 0.5) * kColumns / width));
    const int row = static_cast<int>(std::floor((p.y() + 0.5) * kRows / height));
    if (column < 0 || column >= kColumns || row < 0 || row >= kRows) continue;
    ++coverage.points[row * kColumns + column];
  }
  const auto covered =
      std::count_if(coverage.points.begin(), coverage.points.end(), [](int n) { return n > 0; });
  coverage.fraction = static_cast<double>(covered) / coverage.points.size();
  return coverage;
}

CalibrationSettings CalibrationSettings::FromBoard(const nlohmann::json& board,
                                                   const std::string& file) {
  const JsonReader root(board, file);
  CalibrationSettings s;
  for (const JsonReader& camera : root.Objects("cameras"))
    s.camera_names.push_back(camera.String("name"));
  if (!root.Has("calibration")) return s;
  const JsonReader r = root.Object("calibration");
  r.AllowOnly({"target", "target_id", "mirror_width_mm", "mirror_height_mm", "mirror_bottom_mm",
               "panel_offset_mm", "corner_xy_mm", "lens_chessboard", "limits"});
  if (r.Has("target")) s.target = TargetConfig::Parse(r.Object("target"));
  s.target_id = r.String("target_id", s.target_id);
  s.mirror_width_mm = r.Number("mirror_width_mm", s.mirror_width_mm, 10.0, 1e4);
  s.mirror_height_mm = r.Number("mirror_height_mm", s.mirror_height_mm, 10.0, 1e4);
  s.mirror_bottom_mm = r.Number("mirror_bottom_mm", s.mirror_bottom_mm, -1e4, 1e4);
  s.panel_offset_mm = r.Number("panel_offset_mm", s.panel_offset_mm, 0.0, 1000.0);
  const auto corner = r.Numbers("corner_xy_mm", 2, std::vector<double>{0.0, 600.0});
  s.corner_xy_mm = {corner[0], corner[1]};
  if (r.Has("lens_chessboard")) {
    const JsonReader b = r.Object("lens_chessboard");
    b.AllowOnly({"columns", "rows", "square_mm"});
    s.lens_chessboard.columns = b.Integer("columns", s.lens_chessboard.columns, 2, 100);
    s.lens_chessboard.rows = b.Integer("rows", s.lens_chessboard.rows, 2, 100);
    s.lens_chessboard.square_mm = b.Number("square_mm", s.lens_chessboard.square_mm, 1.0, 500.0);
  }
  if (r.Has("limits")) {
    const JsonReader l = r.Object("limits");
    l.AllowOnly({"max_rms_px", "min_markers_per_view", "min_contrast_dn", "max_edge_sigma_px",
                 "min_white_dn", "min_mirror_angle_deg", "max_mirror_angle_deg",
                 "max_mirror_tilt_deg", "max_corner_offset_mm", "max_yaw_deg", "verify_max_rms_px",
                 "max_panel_offset_error_mm", "min_lens_coverage"});
    CalibrationLimits& x = s.limits;
    x.max_rms_px = l.Number("max_rms_px", x.max_rms_px, 0.001, 100.0);
    x.min_markers_per_view =
        l.Integer("min_markers_per_view", x.min_markers_per_view, 4, kTargetMarkersPerPanel);
    x.min_contrast_dn = l.Number("min_contrast_dn", x.min_contrast_dn, 0.0, 255.0);
    x.max_edge_sigma_px = l.Number("max_edge_sigma_px", x.max_edge_sigma_px, 0.1, 100.0);
    x.min_white_dn = l.Number("min_white_dn", x.min_white_dn, 0.0, 255.0);
    x.min_mirror_angle_deg = l.Number("min_mirror_angle_deg", x.min_mirror_angle_deg, 1.0, 179.0);
    x.max_mirror_angle_deg =
        l.Number("max_mirror_angle_deg", x.max_mirror_angle_deg, x.min_mirror_angle_deg, 179.0);
    x.max_mirror_tilt_deg = l.Number("max_mirror_tilt_deg", x.max_mirror_tilt_deg, 0.0, 90.0);
    x.max_corner_offset_mm = l.Number("max_corner_offset_mm", x.max_corner_offset_mm, 0.0, 1e4);
    x.max_yaw_deg = l.Number("max_yaw_deg", x.max_yaw_deg, 0.0, 180.0);
    x.verify_max_rms_px = l.Number("verify_max_rms_px", x.verify_max_rms_px, 0.001, 100.0);
    x.max_panel_offset_error_mm =
        l.Number("max_panel_offset_error_mm", x.max_panel_offset_error_mm, 0.01, 1000.0);
    x.min_lens_coverage = l.Number("min_lens_coverage", x.min_lens_coverage, 0.0, 1.0);
  }
  return s;
}

CalibrationSettings CalibrationSettings::LoadBoard(const std::filesystem::path& board_json) {
  return FromBoard(JsonReader::ParseFile(board_json), board_json.string());
}

CalibrationResult Calibrate(const std::vector<CameraImage>& images,
                            const CalibrationSettings& settings) {
  const CalibrationTarget target(settings.target);
  CalibrationResult result;
  bool solvable = true;
  std::vector<CameraData> data = DetectAll(images, settings, target, result, solvable);
  for (const CameraData& d : data) CheckCoverage(d.report, settings.limits, result);
  if (!solvable) {
    result.failures.push_back("calibration not attempted: a view has fewer than 4 markers");
    return result;
  }

  // Steps 1 and 2 per camera; the mirrors are shared, so both cameras' estimates are
  // averaged as the start of the joint refinement.
  std::vector<CameraParameters> cameras;
  std::array<MirrorParameters, 2> mirrors{};
  std::array<Eigen::Vector3d, 2> normal_sum{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<double, 2> offset_sum{0.0, 0.0};
  for (const CameraData& d : data) {
    const InitialModel model = InitialiseModel(d, target);
    cameras.push_back(CameraParameters::From(model.camera));
    for (int side = 0; side < 2; ++side) {
      normal_sum[side] += model.mirrors[side].normal;
      offset_sum[side] += model.mirrors[side].offset;
    }
  }
  for (int side = 0; side < 2; ++side) {
    const Eigen::Vector3d n = normal_sum[side].normalized();
    mirrors[side].normal = {n.x(), n.y(), n.z()};
    mirrors[side].offset = offset_sum[side] / data.size();
  }
  auto planes = [&] {
    std::array<Plane, 2> p;
    for (int side = 0; side < 2; ++side) {
      p[side].normal = Eigen::Vector3d(mirrors[side].normal.data()).normalized();
      p[side].offset = mirrors[side].offset;
    }
    return p;
  };
  const std::array<Plane, 2> before = planes();
  for (size_t c = 0; c < data.size(); ++c) {
    const Camera camera = cameras[c].ToCamera(data[c].width, data[c].height);
    for (int v = 0; v < kViews; ++v) {
      result.cameras[c].views[v].rms_before_px =
          Residuals(camera, v == 0 ? nullptr : &before[v - 1], data[c].views[v]).rms;
    }
  }

  // Step 3.
  if (!Refine(data, cameras, mirrors)) {
    result.failures.push_back(
        "the joint refinement found no solution; check the report image for misread markers");
    return result;
  }
  const std::array<Plane, 2> after = planes();

  Calibration calibration;
  calibration.source = data.front().lens ? "mirrorscan calibrate (lens from calibrate-intrinsics)"
                                         : "mirrorscan calibrate (lens from the target alone)";
  calibration.target_id = settings.target_id;
  const auto corners = MirrorCorners(after, settings);
  for (int side = 0; side < 2; ++side) {
    calibration.mirrors.push_back(
        {side == 0 ? "left" : "right", after[side], corners[side], settings.panel_offset_mm});
  }
  double sum2 = 0.0;
  int points = 0;
  for (size_t c = 0; c < data.size(); ++c) {
    CalibrationCamera cam;
    cam.name = data[c].name;
    cam.camera = cameras[c].ToCamera(data[c].width, data[c].height);
    cam.views.push_back({"center", std::nullopt, {}});
    for (int side = 0; side < 2; ++side) {
      CalibrationView view{side == 0 ? "left" : "right", side == 0 ? "left" : "right", {}};
      for (int edge = 0; edge < 4; ++edge) {
        for (int i = 0; i < 16; ++i) {
          const Eigen::Vector3d p =
              corners[side][edge] +
              (corners[side][(edge + 1) % 4] - corners[side][edge]) * (i / 16.0);
          if (const auto px = cam.camera.ProjectWorld(p)) view.outline_px.push_back(*px);
        }
      }
      cam.views.push_back(view);
    }
    for (int v = 0; v < kViews; ++v) {
      ViewReport& report = result.cameras[c].views[v];
      const Rms r = Residuals(cam.camera, v == 0 ? nullptr : &after[v - 1], data[c].views[v]);
      report.rms_after_px = r.rms;
      report.max_after_px = r.max;
      report.reprojected = r.reprojected;
      const int n = static_cast<int>(r.reprojected.size());
      sum2 += r.rms * r.rms * n;
      points += n;
      calibration.residuals.views.push_back({cam.name, ViewName(report.view), r.rms, r.max, n});
    }
    calibration.cameras.push_back(cam);
  }
  calibration.residuals.reprojection_rms_px = points ? std::sqrt(sum2 / points) : 0.0;

  AddRmsChecks(result.cameras, settings.limits.max_rms_px, "from the calibrated model", result);
  CheckCabinet(after, settings, result);
  result.calibration = calibration;
  result.ok = result.failures.empty();
  return result;
}

CalibrationResult Verify(const std::vector<CameraImage>& images,
                         const CalibrationSettings& settings, const Calibration& existing) {
  const CalibrationTarget target(settings.target);
  CalibrationResult result;
  bool solvable = true;
  const std::vector<CameraData> data = DetectAll(images, settings, target, result, solvable);
  for (size_t c = 0; c < data.size(); ++c) {
    const CalibrationCamera* cam = existing.FindCamera(data[c].name);
    if (!cam) {
      throw std::invalid_argument("camera \"" + data[c].name + "\" is not in the calibration");
    }
    for (int v = 0; v < kViews; ++v) {
      const CalibrationMirror* mirror =
          v == 0 ? nullptr : existing.FindMirror(ViewName(static_cast<ViewId>(v)));
      ViewReport& report = result.cameras[c].views[v];
      const Rms r = Residuals(cam->camera, mirror ? &mirror->plane : nullptr, data[c].views[v]);
      report.rms_before_px = r.rms;
      report.rms_after_px = r.rms;
      report.max_after_px = r.max;
      report.reprojected = r.reprojected;
    }
  }
  AddRmsChecks(result.cameras, settings.limits.verify_max_rms_px,
               "from where the stored calibration puts them", result);
  if (!result.failures.empty()) {
    result.failures.push_back("the cabinet differs from its calibration: recalibrate");
  }
  result.calibration = existing;
  result.ok = result.failures.empty();
  return result;
}

nlohmann::json CalibrationResult::ReportJson() const {
  nlohmann::json cameras_json = nlohmann::json::array();
  for (const CameraReport& c : cameras) {
    nlohmann::json views = nlohmann::json::array();
    for (const ViewReport& v : c.views) {
      views.push_back({{"view", ViewName(v.view)},
                       {"markers_found", v.found},
                       {"markers_missing", v.missing},
                       {"markers_rejected", v.rejected},
                       {"contrast_dn", v.contrast_dn},
                       {"edge_sigma_px", v.edge_sigma_px},
                       {"rms_before_px", v.rms_before_px},
                       {"rms_after_px", v.rms_after_px},
                       {"max_after_px", v.max_after_px}});
    }
    // One string per row of cells: '#' with data, '.' without.
    nlohmann::json cells = nlohmann::json::array();
    for (int row = 0; row < LensCoverage::kRows; ++row) {
      std::string line;
      for (int column = 0; column < LensCoverage::kColumns; ++column)
        line += c.coverage.points[row * LensCoverage::kColumns + column] > 0 ? '#' : '.';
      cells.push_back(line);
    }
    cameras_json.push_back({{"name", c.name},
                            {"white_dn", c.white_dn},
                            {"views", views},
                            {"lens",
                             {{"fixed", c.coverage.lens_fixed},
                              {"coverage", c.coverage.fraction},
                              {"cells", cells}}}});
  }
  nlohmann::json checks_json = nlohmann::json::array();
  for (const Check& c : checks) {
    checks_json.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit}, {"ok", c.ok}});
  }
  nlohmann::json report = {
      {"ok", ok}, {"failures", failures}, {"cameras", cameras_json}, {"checks", checks_json}};
  if (calibration) {
    nlohmann::json mirrors = nlohmann::json::array();
    for (const auto& m : calibration->mirrors) {
      mirrors.push_back({{"name", m.name},
                         {"normal", {m.plane.normal.x(), m.plane.normal.y(), m.plane.normal.z()}},
                         {"offset_mm", m.plane.offset}});
    }
    report["mirrors"] = mirrors;
    report["content_hash"] = calibration->ContentHash();
  }
  return report;
}

cv::Mat DrawReport(const CameraImage& image, const CameraReport& report) {
  cv::Mat out;
  cv::cvtColor(image.gray, out, cv::COLOR_GRAY2BGR);
  const cv::Scalar green(0, 200, 0), red(0, 0, 255);
  // Lens coverage: cells with no data tinted red, a faint grid over the rest.
  cv::Mat tint = out.clone();
  for (int row = 0; row < LensCoverage::kRows; ++row) {
    for (int column = 0; column < LensCoverage::kColumns; ++column) {
      const cv::Rect cell(column * out.cols / LensCoverage::kColumns,
                          row * out.rows / LensCoverage::kRows, out.cols / LensCoverage::kColumns,
                          out.rows / LensCoverage::kRows);
      if (report.coverage.points[row * LensCoverage::kColumns + column] == 0) {
        cv::rectangle(tint, cell, red, cv::FILLED);
      }
      cv::rectangle(out, cell, cv::Scalar(90, 120, 90), 1);
    }
  }
  cv::addWeighted(tint, 0.3, out, 0.7, 0.0, out);
  int line = 0;
  for (const ViewReport& v : report.views) {
    for (size_t i = 0; i < v.observed.size(); ++i) {
      const cv::Point2d seen(v.observed[i].x(), v.observed[i].y());
      cv::circle(out, seen, 3, green, 1, cv::LINE_AA);
      if (i < v.reprojected.size()) {
        const cv::Point2d projected(v.reprojected[i].x(), v.reprojected[i].y());
        cv::drawMarker(out, projected, red, cv::MARKER_CROSS, 6, 1, cv::LINE_AA);
        const Eigen::Vector2d tip = v.observed[i] + 50.0 * (v.reprojected[i] - v.observed[i]);
        cv::line(out, seen, cv::Point2d(tip.x(), tip.y()), red, 1, cv::LINE_AA);
      }
    }
    std::ostringstream text;
    text << ViewName(v.view) << ": " << v.found.size() << " markers, RMS "
         << Format("%.3f", v.rms_after_px) << " px";
    cv::putText(out, text.str(), cv::Point(10, 24 + 22 * line++), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  cv::putText(out,
              "lens data on " + Format("%.0f", 100.0 * report.coverage.fraction) +
                  "% of the image (red: none)" +
                  (report.coverage.lens_fixed ? ", lens fixed" : ", lens from the target"),
              cv::Point(10, 24 + 22 * line++), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  return out;
}

}  // namespace mirrorscan::calibration

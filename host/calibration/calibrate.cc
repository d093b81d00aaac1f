#include "host/calibration/calibrate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "host/calibration/checks.h"
#include "host/calibration/detection.h"
#include "host/calibration/refinement.h"

namespace mirrorscan::calibration {

namespace {

using internal::AddRmsChecks;
using internal::CameraData;
using internal::CameraParameters;
using internal::CheckCabinet;
using internal::CheckCoverage;
using internal::DetectAll;
using internal::MirrorCorners;
using internal::MirrorParameters;
using internal::Refine;
using internal::ViewPoints;

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

}  // namespace

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

}  // namespace mirrorscan::calibration

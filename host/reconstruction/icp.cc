#include "host/reconstruction/icp.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>

namespace mirrorscan::reconstruction {

namespace {

constexpr size_t kMinGroupPoints = 500;
constexpr size_t kMaxTargetPoints = 60000;

open3d::geometry::PointCloud ToOpen3d(const PointCloud& cloud, const std::vector<size_t>& indices,
                                      size_t max_points) {
  open3d::geometry::PointCloud out;
  const size_t step = std::max<size_t>(1, indices.size() / max_points);
  for (size_t i = 0; i < indices.size(); i += step) {
    const CloudPoint& p = cloud.points[indices[i]];
    out.points_.push_back(p.point_in_world.cast<double>());
    out.normals_.push_back(p.normal.cast<double>());
  }
  return out;
}

}  // namespace

IcpSummary RefineViews(PointCloud* cloud, double max_distance_mm) {
  namespace reg = open3d::pipelines::registration;
  IcpSummary summary;
  summary.ran = true;
  std::map<std::pair<int, int>, std::vector<size_t>> groups;
  for (size_t i = 0; i < cloud->points.size(); ++i) {
    const CloudPoint& p = cloud->points[i];
    groups[{p.camera, static_cast<int>(p.view)}].push_back(i);
  }
  // The first camera's direct view is the anchor (the paper's most accurate); the other
  // cameras' direct views, then the mirror views, are aligned to everything placed so far.
  std::vector<std::pair<int, int>> order;
  for (const auto& [key, members] : groups)
    if (key.second == static_cast<int>(PointView::kCenter)) order.push_back(key);
  for (const auto& [key, members] : groups)
    if (key.second != static_cast<int>(PointView::kCenter)) order.push_back(key);
  if (order.empty()) return summary;
  std::vector<size_t> placed = groups[order.front()];
  for (size_t g = 1; g < order.size(); ++g) {
    const std::pair<int, int> key = order[g];
    const std::vector<size_t>& members = groups[key];
    if (members.size() < kMinGroupPoints || placed.size() < kMinGroupPoints) {
      placed.insert(placed.end(), members.begin(), members.end());
      continue;
    }
    const auto source = ToOpen3d(*cloud, members, kMaxTargetPoints);
    const auto target = ToOpen3d(*cloud, placed, kMaxTargetPoints);
    IcpSummary::Step step;
    step.what = "camera " + std::to_string(key.first) + " " +
                PointViewName(static_cast<PointView>(key.second)) + " against the views before it";
    const reg::RegistrationResult before =
        reg::EvaluateRegistration(source, target, max_distance_mm);
    const reg::RegistrationResult after = reg::RegistrationICP(
        source, target, max_distance_mm, Eigen::Matrix4d::Identity(),
        reg::TransformationEstimationPointToPlane(), reg::ICPConvergenceCriteria(1e-7, 1e-7, 30));
    step.rmse_before_mm = before.inlier_rmse_;
    step.rmse_after_mm = after.inlier_rmse_;
    const Eigen::Matrix3d rotation = after.transformation_.topLeftCorner<3, 3>();
    const Eigen::Vector3d translation = after.transformation_.topRightCorner<3, 1>();
    step.rotation_deg =
        std::acos(std::clamp((rotation.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / M_PI;
    step.translation_mm = translation.norm();
    step.applied = before.fitness_ >= 0.2 && after.fitness_ >= 0.2 &&
                   after.inlier_rmse_ < 0.9 * before.inlier_rmse_;
    if (step.applied) {
      const Eigen::Matrix3f r = rotation.cast<float>();
      const Eigen::Vector3f t = translation.cast<float>();
      for (size_t i : members) {
        CloudPoint& p = cloud->points[i];
        p.point_in_world = r * p.point_in_world + t;
        p.normal = r * p.normal;
      }
    }
    summary.steps.push_back(step);
    placed.insert(placed.end(), members.begin(), members.end());
  }
  return summary;
}

}  // namespace mirrorscan::reconstruction

#include "host/measurement/head_cap.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>

namespace mirrorscan::measurement {
namespace {

constexpr int kMinPoints = 30;

// A point's distance from the cap along the ray from its centre: (r - 1) |d| / r, with r
// the ellipsoid's radius function at d, the point in the cap's frame.
struct CapResidual {
  Eigen::Vector3d point;

  template <typename T>
  bool operator()(const T* centre, const T* axes, const T* yaw, T* residual) const {
    const T dx = T(point.x()) - centre[0], dy = T(point.y()) - centre[1],
            dz = T(point.z()) - centre[2];
    const T c = ceres::cos(yaw[0]), s = ceres::sin(yaw[0]);
    const T x = c * dx + s * dy, y = -s * dx + c * dy;
    const T& b = y < T(0) ? axes[1] : axes[2];
    const T r2 =
        (x / axes[0]) * (x / axes[0]) + (y / b) * (y / b) + (dz / axes[3]) * (dz / axes[3]);
    const T r = ceres::sqrt(r2);
    const T length = ceres::sqrt(x * x + y * y + dz * dz);
    residual[0] = (r - T(1)) * length / r;
    return true;
  }
};

}  // namespace

std::optional<HeadCapFit> FitHeadCap(const std::vector<Eigen::Vector3d>& points,
                                     const Eigen::Vector2d& lateral) {
  if (static_cast<int>(points.size()) < kMinPoints) return std::nullopt;
  // Start from the lowest band's ring: centre over it, a sphere-like cap of its radius.
  double z_min = points.front().z(), z_max = points.front().z();
  for (const Eigen::Vector3d& p : points) {
    z_min = std::min(z_min, p.z());
    z_max = std::max(z_max, p.z());
  }
  Eigen::Vector2d ring_centre = Eigen::Vector2d::Zero();
  std::vector<const Eigen::Vector3d*> ring;
  for (const Eigen::Vector3d& p : points) {
    if (p.z() < z_min + 5.0) ring.push_back(&p);
  }
  for (const Eigen::Vector3d* p : ring) ring_centre += p->head<2>();
  ring_centre /= static_cast<double>(ring.size());
  std::vector<double> radii;
  for (const Eigen::Vector3d* p : ring) radii.push_back((p->head<2>() - ring_centre).norm());
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  const double radius = std::max(radii[radii.size() / 2], 1.0);

  double centre[3] = {ring_centre.x(), ring_centre.y(), z_max - 1.2 * radius};
  double axes[4] = {radius, radius, radius, 1.2 * radius};
  double yaw[1] = {std::atan2(lateral.y(), lateral.x())};
  ceres::Problem problem;
  for (const Eigen::Vector3d& p : points) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<CapResidual, 1, 3, 4, 1>(new CapResidual{p}), nullptr,
        centre, axes, yaw);
  }
  for (int i = 0; i < 4; ++i) {  // keeps the radius function finite; no head is near
    problem.SetParameterLowerBound(axes, i, 1.0);
    problem.SetParameterUpperBound(axes, i, 1000.0);
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return std::nullopt;

  HeadCapFit fit;
  fit.top = Eigen::Vector3d(centre[0], centre[1], centre[2] + axes[3]);
  fit.rms_mm = std::sqrt(2.0 * summary.final_cost / static_cast<double>(points.size()));
  return fit;
}

}  // namespace mirrorscan::measurement

#include "host/calibration/refinement.h"

#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>

namespace mirrorscan::calibration::internal {
namespace {

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

}  // namespace

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

}  // namespace mirrorscan::calibration::internal

#include "host/reconstruction/surface_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/voxel_box.h"

namespace mirrorscan::reconstruction {

SurfaceDrops DropOffSurface(const ReconstructOptions& options, int threads,
                            const std::vector<uint8_t>& suspect, std::vector<CloudPoint>* points) {
  const double radius = options.surface_check_radius_mm;
  const float threshold = static_cast<float>(options.surface_check_confidence);
  const VoxelBox box(options.cylinder, radius);
  // Each confident point's cell; the points' places then by cell, side by side in memory.
  constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> cell_of(points->size(), kNone);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      if (cp.confidence < threshold || suspect[i]) continue;
      if (const auto cell = box.Index(cp.point_in_world.cast<double>()))
        cell_of[i] = static_cast<uint32_t>(*cell);
    }
  });
  std::vector<uint32_t> start(box.Voxels() + 1, 0);
  for (const uint32_t cell : cell_of)
    if (cell != kNone) ++start[cell + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Eigen::Vector3f> by_cell(start[box.Voxels()]);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < points->size(); ++i)
      if (cell_of[i] != kNone) by_cell[fill[cell_of[i]]++] = (*points)[i].point_in_world;
  }
  constexpr int kMinNeighbours = 6;
  const double radius2 = radius * radius;
  std::vector<uint8_t> drop(points->size(), 0);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      if (cp.confidence >= threshold && !suspect[i]) continue;
      const Eigen::Vector3d at = cp.point_in_world.cast<double>();
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
      int n = 0;
      box.ForNeighbourhood(at, [&](size_t cell) {
        for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
          const Eigen::Vector3d q = by_cell[k].cast<double>() - at;
          if (q.squaredNorm() > radius2) continue;
          sum += q;
          outer += q * q.transpose();
          ++n;
        }
      });
      // A suspect needs the surface's word: isolated phantoms have none.
      if (n < kMinNeighbours) {
        drop[i] =
            suspect[i] || cp.rule == DecidedBy::kColumnCount || cp.rule == DecidedBy::kLabelVote;
        continue;
      }
      const Eigen::Vector3d mean = sum / n;
      const Eigen::Matrix3d covariance = outer / n - mean * mean.transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
      const double rms = std::sqrt(std::max(0.0, solver.eigenvalues()(0)));
      const double off = std::abs(solver.eigenvectors().col(0).dot(-mean));
      // A suspect is already off its neighbours: where the plane says nothing (an edge, a
      // fold) it is not given the benefit of the doubt that a weak point gets.
      drop[i] = suspect[i] ? off > options.surface_check_outlier_mm
                           : off > options.surface_check_max_mm && off > 3.0 * rms;
    }
  });
  SurfaceDrops drops;
  size_t kept = 0;
  for (size_t i = 0; i < points->size(); ++i) {
    if (!drop[i])
      (*points)[kept++] = (*points)[i];
    else
      ++(suspect[i] ? drops.suspect : drops.weak);
  }
  points->resize(kept);
  return drops;
}

}  // namespace mirrorscan::reconstruction

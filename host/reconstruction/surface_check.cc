#include "host/reconstruction/surface_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/voxel_box.h"

namespace mirrorscan::reconstruction {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr int kMinNeighbours = 6;
// Normals within 60° of each other: one surface (a box's faces meet at 90°).
const double kSameSurfaceCos = std::cos(60.0 * kDegToRad);

// Neighbours nearer in height than this lie on the point's own slice: the lasers light
// the same heights, so a whole slice shares one frame's fault (a line across the
// underwear's hem is off in every view and for every laser alike).
constexpr double kOtherSliceMm = 2.0;
// A surface whose normal's height component is below this is steep (within ~45° of
// vertical).
constexpr float kSteepNormalZ = 0.7f;
// Judges along one line say nothing of a plane: their RMS across it must reach this.
constexpr double kMinSpreadMm = 2.0;

// A point as a judge: where it is, which camera saw it, how squarely, and whether it is
// confident (the confident judge weak ones; every point judges a weak one that has too
// few confident neighbours, from the slices above and below it).
struct Judge {
  Eigen::Vector3f point;
  uint8_t camera;
  float sin_angle;
  bool confident;
};

// The plane of neighbours accumulated one by one: the point's distance from it and the
// neighbours' RMS about it.
class PlaneFit {
 public:
  void Add(const Eigen::Vector3d& q) {
    sum_ += q;
    outer_ += q * q.transpose();
    ++n_;
  }
  int count() const { return n_; }
  Eigen::Vector3d mean() const { return sum_ / n_; }
  // The neighbours were added relative to the point judged: the point is the origin.
  // `spread`: the neighbours' RMS across the plane's narrower direction (near 0 when they
  // lie along one line, which any plane through it fits).
  void Fit(double* off, double* rms, Eigen::Vector3d* normal = nullptr,
           double* spread = nullptr) const {
    const Eigen::Vector3d mean = sum_ / n_;
    const Eigen::Matrix3d covariance = outer_ / n_ - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
    *rms = std::sqrt(std::max(0.0, solver.eigenvalues()(0)));
    *off = std::abs(solver.eigenvectors().col(0).dot(-mean));
    if (normal) *normal = solver.eigenvectors().col(0);
    if (spread) *spread = std::sqrt(std::max(0.0, solver.eigenvalues()(1)));
  }

 private:
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer_ = Eigen::Matrix3d::Zero();
  int n_ = 0;
};

enum Drop : uint8_t { kKeep = 0, kWeak, kSuspect, kFlat };

// A weak point with too few confident neighbours, judged by every point within `radius`
// on another slice: off when further than max_mm from their plane and 3 times its RMS.
// Where they are too few or lie along one line (a point 12 mm off, at the lower camera's
// flat top rows, has only a stripe of the next slice that near), those within twice the
// radius judge. The plane is fitted twice, the second time to the neighbours within 2 RMS
// (at least 1 mm) of the first: along a hem the next slices are doubted too and some lie
// off, which would tilt it. A point on a steep surface that no other slice carries is off
// (a steep surface is lit every few millimetres of height; a level one, a shoulder's top,
// may lie on one slice alone, but then not as a few points in the air).
bool OffOtherSlices(const VoxelBox& box, const std::vector<uint32_t>& start,
                    const std::vector<Judge>& by_cell, const Eigen::Vector3d& at, double radius,
                    double max_mm, float normal_z) {
  thread_local std::vector<Eigen::Vector3d> near;
  near.clear();
  const double far2 = 4.0 * radius * radius;
  int own_slice = 0;  // Within the radius (the point itself among them).
  box.ForNeighbourhood(
      at,
      [&](size_t cell) {
        for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
          const Eigen::Vector3d q = by_cell[k].point.cast<double>() - at;
          if (q.squaredNorm() > far2) continue;
          if (std::abs(q.z()) >= kOtherSliceMm)
            near.push_back(q);
          else if (q.squaredNorm() <= radius * radius)
            ++own_slice;
        }
      },
      2);
  const auto fit = [&](double reach2, double* off, double* rms) {
    PlaneFit first;
    for (const Eigen::Vector3d& q : near)
      if (q.squaredNorm() <= reach2) first.Add(q);
    if (first.count() < kMinNeighbours) return false;
    double spread = 0;
    Eigen::Vector3d normal;
    first.Fit(off, rms, &normal, &spread);
    if (spread < kMinSpreadMm) return false;
    const Eigen::Vector3d mean = first.mean();  // The first plane passes through it.
    const double keep = std::max(1.0, 2.0 * *rms);
    PlaneFit second;
    for (const Eigen::Vector3d& q : near)
      if (q.squaredNorm() <= reach2 && std::abs(normal.dot(q - mean)) <= keep) second.Add(q);
    if (second.count() < kMinNeighbours) return true;
    second.Fit(off, rms, nullptr, &spread);
    return spread >= kMinSpreadMm;
  };
  double off = 0, rms = 0;
  if (!fit(radius * radius, &off, &rms) && !fit(far2, &off, &rms))
    return std::abs(normal_z) < kSteepNormalZ || own_slice <= kMinNeighbours;
  return off > max_mm && off > 3.0 * rms;
}

}  // namespace

SurfaceDrops DropOffSurface(const ReconstructOptions& options, int threads, const PointNotes& notes,
                            std::vector<CloudPoint>* points) {
  const std::vector<uint8_t>& suspect = notes.suspect;
  const double radius = options.surface_check_radius_mm;
  const float threshold = static_cast<float>(options.surface_check_confidence);
  const float flat_sin = static_cast<float>(std::sin(options.flat_check_deg * kDegToRad));
  const VoxelBox box(options.cylinder, radius);
  // Each confident point's cell; the points then by cell, side by side in memory.
  constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> cell_of(points->size(), kNone);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      if (suspect[i]) continue;
      if (const auto cell = box.Index(cp.point_in_world.cast<double>()))
        cell_of[i] = static_cast<uint32_t>(*cell);
    }
  });
  std::vector<uint32_t> start(box.Voxels() + 1, 0);
  for (const uint32_t cell : cell_of)
    if (cell != kNone) ++start[cell + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Judge> by_cell(start[box.Voxels()]);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < points->size(); ++i)
      if (cell_of[i] != kNone)
        by_cell[fill[cell_of[i]]++] = {(*points)[i].point_in_world, (*points)[i].camera,
                                       notes.sin_angle[i], (*points)[i].confidence >= threshold};
  }
  const double radius2 = radius * radius;
  std::vector<uint8_t> drop(points->size(), kKeep);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      const bool weak = cp.confidence < threshold;
      const bool flat = notes.sin_angle[i] < flat_sin;
      const bool doubted = weak || suspect[i];
      if (!doubted && !flat) continue;
      const Eigen::Vector3d at = cp.point_in_world.cast<double>();
      // All confident neighbours; and those another camera saw more squarely.
      PlaneFit all, squarer;
      const float squarer_sin = static_cast<float>(options.flat_check_ratio) * notes.sin_angle[i];
      box.ForNeighbourhood(at, [&](size_t cell) {
        for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
          const Judge& judge = by_cell[k];
          const Eigen::Vector3d q = judge.point.cast<double>() - at;
          if (q.squaredNorm() > radius2) continue;
          if (!judge.confident) continue;
          if (doubted) all.Add(q);
          if (flat && judge.camera != cp.camera && judge.sin_angle >= squarer_sin) squarer.Add(q);
        }
      });
      double off = 0, rms = 0;
      // A ray flat to its plane puts the peak's error along itself, many times over (the
      // lower camera's top rows: f01's points beyond 5 mm, 0.5-0.8 px off where the line
      // ends at a silhouette): where another camera sees the surface more squarely, its
      // points say where the surface is. Only the same surface judges: near an edge the
      // other camera may see the other face alone (the point's normal then disagrees).
      if (flat && squarer.count() >= kMinNeighbours) {
        Eigen::Vector3d normal;
        squarer.Fit(&off, &rms, &normal);
        if (std::abs(normal.dot(cp.normal.cast<double>())) >= kSameSurfaceCos &&
            off > options.surface_check_max_mm && off > 3.0 * rms) {
          drop[i] = kFlat;
          continue;
        }
      }
      if (!doubted) continue;
      // A suspect needs the surface's word: isolated phantoms have none.
      if (all.count() < kMinNeighbours) {
        if (suspect[i] || cp.rule == DecidedBy::kColumnCount || cp.rule == DecidedBy::kLabelVote) {
          drop[i] = suspect[i] ? kSuspect : kWeak;
          continue;
        }
        // Where the weak points cluster (a whole band of slices the extractor doubted, along
        // a hem), the slices above and below judge (OffOtherSlices).
        if (OffOtherSlices(box, start, by_cell, at, radius, options.surface_check_max_mm,
                           cp.normal.z()))
          drop[i] = kWeak;
        continue;
      }
      all.Fit(&off, &rms);
      // A suspect is already off its neighbours: where the plane says nothing (an edge, a
      // fold) it is not given the benefit of the doubt that a weak point gets.
      if (suspect[i] ? off > options.surface_check_outlier_mm
                     : off > options.surface_check_max_mm && off > 3.0 * rms)
        drop[i] = suspect[i] ? kSuspect : kWeak;
    }
  });
  SurfaceDrops drops;
  size_t kept = 0;
  for (size_t i = 0; i < points->size(); ++i) {
    switch (drop[i]) {
      case kKeep:
        (*points)[kept++] = (*points)[i];
        break;
      case kWeak:
        ++drops.weak;
        break;
      case kSuspect:
        ++drops.suspect;
        break;
      case kFlat:
        ++drops.flat;
        break;
    }
  }
  points->resize(kept);
  return drops;
}

}  // namespace mirrorscan::reconstruction

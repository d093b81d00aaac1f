#include "host/reconstruction/rules/volume.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/laser_sequence.h"
#include "host/reconstruction/voxel_box.h"

namespace mirrorscan::reconstruction {

namespace {

// The voxels (10 mm) near a point that was decided alone: the subject's volume as the scan
// itself carves it. A wrong laser's hypothesis lies on the ray behind the surface the ray
// really met, where nothing was seen.
constexpr double kOccupancyVoxelMm = 10.0;

// The surface the scan has seen so far, voxel by voxel (not spread): whether a mirror view's
// ray passed through it on the way to the point. The mannequin's upper camera sees the
// torso's back in a mirror where nothing was decided alone yet, and the same ray, on
// through the torso, meets another laser's plane beside the forearm, in the carved volume:
// without this the volume took laser k - 1 there for ~800 peaks, and the vote then dropped
// them as conflicts. The direct view is not walked: what the camera sees directly is
// mostly decided alone already, and walking it too, the lower camera's rays past the
// turned cuboid tripod's thin front leg to the leg behind it counted as hidden
// (cuboid3-yaw30: 438 -> 549 wrong points), with nothing gained on the mannequin.
class SeenSurface {
 public:
  SeenSurface(const BoundingCylinder& c, const Geometry& g)
      : voxels_(c, kOccupancyVoxelMm), mirrors_(g.mirrors) {}
  void Add(const Hypothesis& h) {
    if (!h.Background()) voxels_.Add(h.point, 1);
  }
  // Walks back from the point along its last ray segment, from clear of the point's own
  // surface to the mirror the segment came from. The surfaces at the peak's other
  // hypotheses (`others`, `count` of them, h among them) do not count: the ray runs through
  // those whatever it really met.
  bool Hides(const Hypothesis& h, const Hypothesis* others, int count) const {
    const int view = h.key / kMaxLasers;
    if (view == static_cast<int>(PointView::kCenter)) return false;
    // The last bounce: left and right-left end on mirror 0, right and left-right on 1.
    const bool left = view == static_cast<int>(PointView::kLeft) ||
                      view == static_cast<int>(PointView::kRightLeft);
    const Plane& mirror = mirrors_[left ? 0 : 1];
    const double approach = mirror.normal.dot(h.last_direction);
    if (approach <= 1e-9) return false;
    const double length = mirror.SignedDistance(h.point) / approach;
    constexpr double kClear2 = kOwnSurfaceMm * kOwnSurfaceMm;
    for (double s = kOwnSurfaceMm; s < length; s += kStepMm) {
      const Eigen::Vector3d at = h.point - s * h.last_direction;
      if (!voxels_.At(at)) continue;
      if (std::none_of(others, others + count, [&](const Hypothesis& o) {
            return &o != &h && (o.point - at).squaredNorm() < kClear2;
          }))
        return true;
    }
    return false;
  }

 private:
  // Clear of the point's own surface: at 40 mm a ray grazing it at 15 degrees has left its
  // voxels.
  static constexpr double kOwnSurfaceMm = 40.0;
  static constexpr double kStepMm = 5.0;
  NeighbourhoodBits<uint8_t> voxels_;
  std::array<Plane, 2> mirrors_;
};

}  // namespace

void DecideByVolume(std::vector<PeakState>* peaks, const Hypotheses& hyp,
                    const BoundingCylinder& cylinder, const Geometry& g, int threads) {
  NeighbourhoodBits<uint8_t> occupied(cylinder, kOccupancyVoxelMm);
  SeenSurface seen(cylinder, g);
  for (const PeakState& p : *peaks)
    if (p.rule == Rule::kCylinder || p.rule == Rule::kStereo) {
      occupied.Add(hyp[p.first_hypothesis + p.chosen].point, 1);
      seen.Add(hyp[p.first_hypothesis + p.chosen]);
    }
  occupied.Spread(threads);
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.rule != Rule::kNone || p.hypotheses < 2) continue;
      const uint32_t allowed = SequenceAllows(&hyp[p.first_hypothesis], p.hypotheses);
      int found = -1, count = 0;
      for (int h = 0; h < p.hypotheses; ++h) {
        const Hypothesis& x = hyp[p.first_hypothesis + h];
        if (!(allowed >> h & 1u)) continue;
        if (occupied.At(x.point) && !seen.Hides(x, &hyp[p.first_hypothesis], p.hypotheses)) {
          found = h;
          ++count;
        }
      }
      if (count == 1) {
        p.chosen = static_cast<int16_t>(found);
        p.rule = Rule::kVolume;
      }
    }
  });
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/free_space.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {

namespace {

// Per camera and image column, what the decided peaks saw along their pixel's ray: the
// row and the path length, rows ascending. A pixel's ray meets one surface first, whatever
// laser lights it and whenever.
class SeenAlongRays {
 public:
  struct Seen {
    float v;
    float path_mm;
    uint8_t laser;
  };

  SeenAlongRays(const ScanArchive& archive, const PeakTable& table, const Hypotheses& hyp,
                size_t cameras) {
    width_ = table.columns;
    first_.assign(cameras * width_ + 1, 0);
    auto slot = [&](const PeakState& p) { return archive.frames[p.frame].camera * width_ + p.u; };
    for (const PeakState& p : table.peaks)
      if (p.chosen >= 0) ++first_[slot(p) + 1];
    for (size_t i = 1; i < first_.size(); ++i) first_[i] += first_[i - 1];
    seen_.resize(first_.back());
    std::vector<uint32_t> fill(first_.begin(), first_.end() - 1);
    for (const PeakState& p : table.peaks) {
      if (p.chosen < 0) continue;
      const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
      seen_[fill[slot(p)]++] = {p.v, h.path_mm, static_cast<uint8_t>(h.key % kMaxLasers)};
    }
    for (size_t i = 0; i + 1 < first_.size(); ++i)
      std::sort(seen_.begin() + first_[i], seen_.begin() + first_[i + 1],
                [](const Seen& a, const Seen& b) { return a.v < b.v; });
  }

  // Calls f for every peak seen in the camera's column u within rows of v.
  template <typename F>
  void ForEachNear(size_t camera, int u, double v, double rows, F f) const {
    if (u < 0 || u >= width_) return;
    const auto begin = seen_.begin() + first_[camera * width_ + u];
    const auto end = seen_.begin() + first_[camera * width_ + u + 1];
    const float lo = static_cast<float>(v - rows);
    for (auto it = std::lower_bound(begin, end, lo, [](const Seen&s, float x) { return s.v < x; });
         it != end && it->v <= v + rows; ++it)
      f(*it);
  }

 private:
  int width_ = 1;
  std::vector<uint32_t> first_;  // per (camera, column), and one past the end
  std::vector<Seen> seen_;
};

}  // namespace

void DropPointsSeenThrough(const Geometry& g, const ScanArchive& archive, const PeakTable& table,
                           const Hypotheses& hyp, const ReconstructOptions& options, int threads,
                           std::vector<PeakState>* peaks, size_t* dropped) {
  const SeenAlongRays seen(archive, table, hyp, g.cameras.size());
  const double rows = options.free_space_rows_px;
  const double tolerance_mm = options.free_space_mm;
  struct View {
    const Camera* camera;
    Eigen::Matrix3d cam_from_world_rotation;
    Eigen::Vector3d cam_from_world_translation;
    Eigen::Vector3d center;
  };
  std::vector<View> views;
  for (const CalibrationCamera* c : g.cameras) {
    if (!c) {
      views.push_back(
          {nullptr, Eigen::Matrix3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
      continue;
    }
    views.push_back({&c->camera, c->camera.cam_from_world.rotation.toRotationMatrix(),
                     c->camera.cam_from_world.translation, c->camera.CenterInWorld()});
  }
  std::vector<uint8_t> drop(peaks->size(), 0);
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const PeakState& p = (*peaks)[i];
      if (p.chosen < 0) continue;
      const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
      if (h.Background()) continue;
      const int laser = h.key % kMaxLasers;
      const size_t own_camera = archive.frames[p.frame].camera;
      size_t others = 0, agree = 0;
      seen.ForEachNear(own_camera, p.u, p.v, rows, [&](const SeenAlongRays::Seen& s) {
        if (s.laser == laser) return;
        ++others;
        if (std::abs(s.path_mm - h.path_mm) <= tolerance_mm * (1.0 + std::abs(s.v - p.v))) ++agree;
      });
      if (others > 0 && agree == 0) {
        drop[i] = 1;
        continue;
      }
      // Other lasers see it there. (A stereo confirmation is no such proof: two cameras'
      // phantoms in front of a mirror met within 3 mm, 250 mm off the body.)
      if (agree > 0) continue;
      size_t through = 0, seen_there = 0;
      const PointView own_view = static_cast<PointView>(h.key / kMaxLasers);
      for (size_t c = 0; c < views.size() && seen_there == 0; ++c) {
        if (!views[c].camera) continue;
        for (int w = 0; w < 3 && seen_there == 0; ++w) {
          if (c == own_camera && w == static_cast<int>(own_view)) continue;
          if (w > 0 && g.mirror_rectangles.empty()) continue;
          const Eigen::Vector3d point = w == 0 ? h.point : g.mirrors[w - 1].ReflectPoint(h.point);
          const Eigen::Vector3d towards = point - views[c].center;
          const double path = towards.norm();
          // A mirror's view sees the point only through its glass.
          if (w > 0) {
            const auto t =
                g.mirror_rectangles[w - 1].Intersect(Ray3d{views[c].center, towards / path});
            if (!t || *t > path) continue;
          }
          const auto pixel = views[c].camera->intrinsics.Project(
              views[c].cam_from_world_rotation * point + views[c].cam_from_world_translation);
          if (!pixel || !views[c].camera->intrinsics.InImage(*pixel)) continue;
          seen.ForEachNear(c, static_cast<int>(std::lround(pixel->x())), pixel->y(), rows,
                           [&](const SeenAlongRays::Seen& s) {
                             const double tolerance =
                                 tolerance_mm * (1.0 + std::abs(s.v - pixel->y()));
                             if (std::abs(s.path_mm - path) <= tolerance) {
                               ++seen_there;
                             } else if (s.path_mm > path + tolerance) {
                               ++through;
                             }
                           });
        }
      }
      if (seen_there == 0 && through >= 2) drop[i] = 1;
    }
  });
  for (size_t i = 0; i < drop.size(); ++i) {
    if (!drop[i]) continue;
    (*peaks)[i].chosen = -1;
    ++*dropped;
  }
}

}  // namespace mirrorscan::reconstruction

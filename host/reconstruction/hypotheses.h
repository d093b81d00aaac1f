#pragma once
// Hypotheses per peak (docs/reconstruction.md, stage 2): every way a peak can have come
// about — a view (the direct ray, once or twice reflected in the mirrors) and a laser whose
// plane that ray segment meets inside the bounding cylinder, clear of the mirrors, or on
// the floor or a panel — each with its point, its angle to the plane and its path length.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/plane.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/archive_check.h"
#include "host/reconstruction/laser_planes.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/rays.h"
#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

constexpr int kViews = 5;
// A (view, laser) pair as one small integer, for votes.
constexpr int kKeys = kViews * kMaxLasers;

inline int Key(PointView view, int laser) { return static_cast<int>(view) * kMaxLasers + laser; }

// One way a peak could have come about: seen along `view`, lit by `laser`.
struct Hypothesis {
  Eigen::Vector3d point;
  Eigen::Vector3d last_direction;  // the ray's last segment (towards the point)
  float sin_angle = 0;             // ray against the laser plane
  float path_mm = 0;               // camera to point along the (unfolded) ray
  uint8_t key = 0;
  bool confirmed = false;  // another camera saw this laser there too
  // The other lasers at this pixel (laser_sequence.h): how many lit this point at their
  // moment in the sweep, and how many would have but the pixel saw nothing then.
  uint8_t sequence_seen = 0;
  uint8_t sequence_missing = 0;
  bool floor = false;  // on the floor below the cylinder: never a point of the subject
  // On a panel beside a mirror, where that laser's line runs: laser-height data that the
  // fit did not take (another camera's line, a stretch it left out), never the subject.
  bool panel = false;
  // A surface that is not the subject: it decides a peak, and the point is dropped.
  bool Background() const { return floor || panel; }
};

// Every peak's hypotheses in one allocation. Each chunk of frames writes its own stretch,
// sized for the most its peaks can have: no chunk waits for another, nothing is copied
// after, and the stretches' unused tails are never written, so that memory is never
// touched (its first touch, not the writing, is what costs on this machine). Only a peak's
// own [first_hypothesis, first_hypothesis + hypotheses) is ever read.
class Hypotheses {
 public:
  explicit Hypotheses(size_t capacity)
      : data_(std::allocator<Hypothesis>().allocate(capacity)), capacity_(capacity) {}
  ~Hypotheses() {
    if (data_) std::allocator<Hypothesis>().deallocate(data_, capacity_);
  }
  Hypotheses(Hypotheses&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), capacity_(std::exchange(other.capacity_, 0)) {}
  Hypotheses(const Hypotheses&) = delete;
  Hypotheses& operator=(const Hypotheses&) = delete;
  Hypothesis& operator[](size_t i) { return data_[i]; }
  const Hypothesis& operator[](size_t i) const { return data_[i]; }

  // Appends into [next, end) of the store.
  struct Writer {
    Hypotheses* store;
    uint32_t next, end;
    uint32_t size() const { return next; }
    void push_back(const Hypothesis& h) {
      if (next >= end) throw std::logic_error("more hypotheses than a peak can have");
      new (store->data_ + next) Hypothesis(h);
      ++next;
    }
  };

 private:
  static_assert(std::is_trivially_destructible_v<Hypothesis>);
  Hypothesis* data_;
  size_t capacity_;
};

// Every used peak's hypotheses (PeakState::first_hypothesis, hypotheses, region), counted
// into the summary: dropped panel (the laser fit's), no_ray, outside (none at all).
// ReconstructError when the peaks are more than the store can index.
Hypotheses Hypothesize(const ScanArchive& archive, const Geometry& g, const LaserPlanes& planes,
                       const ReconstructOptions& options,
                       const std::vector<std::optional<Ray3d>>& rays, int threads, PeakTable* table,
                       ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

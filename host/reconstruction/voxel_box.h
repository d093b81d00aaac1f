#pragma once
// The spatial indexes of the rules and filters: the bounding cylinder's box in cubes, and
// per cube the OR of bits set by points in it or in its 26 neighbours.
#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/bounding_cylinder.h"

namespace mirrorscan::reconstruction {

// The bounding cylinder's box cut into cubes `voxel_mm` on a side: the index of a point's
// voxel, and of its own and its 26 neighbours' (the grids below share it). With a margin,
// the grid has that many more voxels on every side, which only IndexInMargin reaches.
class VoxelBox {
 public:
  VoxelBox(const BoundingCylinder& c, double voxel_mm, int margin = 0)
      : voxel_mm_(voxel_mm), margin_(margin) {
    origin_ =
        Eigen::Vector3d(c.center_mm.x() - c.radius_mm, c.center_mm.y() - c.radius_mm, c.bottom_mm);
    size_ = (Eigen::Vector3d(2 * c.radius_mm, 2 * c.radius_mm, c.top_mm - c.bottom_mm) / voxel_mm)
                .array()
                .ceil()
                .cast<int>() +
            1 + 2 * margin;
  }
  size_t Voxels() const { return static_cast<size_t>(size_.x()) * size_.y() * size_.z(); }
  const Eigen::Vector3i& Size() const { return size_; }
  std::optional<size_t> Index(const Eigen::Vector3d& point) const {
    const Eigen::Vector3i c = Cell(point);
    if (!Inside(c)) return std::nullopt;
    return Flat(c);
  }
  std::optional<size_t> IndexInMargin(const Eigen::Vector3d& point) const {
    const Eigen::Vector3i c = Cell(point);
    if (!(c.array() >= 0).all() || !(c.array() < size_.array()).all()) return std::nullopt;
    return Flat(c);
  }
  // The voxels within `reach` of the point's along each axis (27 for reach 1).
  template <typename F>
  void ForNeighbourhood(const Eigen::Vector3d& point, F&& visit, int reach = 1) const {
    const Eigen::Vector3i at = Cell(point);
    for (int dz = -reach; dz <= reach; ++dz)
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
          const Eigen::Vector3i c = at + Eigen::Vector3i(dx, dy, dz);
          if (Inside(c)) visit(Flat(c));
        }
  }

 private:
  // The margin added as an integer: the same voxel boundaries as without it.
  Eigen::Vector3i Cell(const Eigen::Vector3d& point) const {
    return ((point - origin_) / voxel_mm_).array().floor().cast<int>() + margin_;
  }
  bool Inside(const Eigen::Vector3i& c) const {
    return (c.array() >= margin_).all() && (c.array() < size_.array() - margin_).all();
  }
  size_t Flat(const Eigen::Vector3i& c) const {
    return (static_cast<size_t>(c.z()) * size_.y() + c.y()) * size_.x() + c.x();
  }
  double voxel_mm_;
  int margin_;
  Eigen::Vector3d origin_;
  Eigen::Vector3i size_;
};

// Per voxel, the OR of the bits added at points in it or in any of its 26 neighbours. Each
// point marks its own voxel only (a point up to one voxel outside the box marks the margin,
// from where it still reaches in); Spread() then ORs every voxel with its two neighbours
// along x, y and z in turn, which is the 3×3×3 neighbourhood. Marking all 27 voxels per
// point instead cost ten times the writes, scattered.
template <typename Bits>
class NeighbourhoodBits {
 public:
  NeighbourhoodBits(const BoundingCylinder& c, double voxel_mm)
      : box_(c, voxel_mm, 1), cells_(box_.Voxels(), 0) {}
  void Add(const Eigen::Vector3d& point, Bits bits) {
    if (const auto i = box_.IndexInMargin(point)) cells_[*i] |= bits;
  }
  void Spread(int threads) {
    const Eigen::Vector3i& size = box_.Size();
    const size_t sx = size.x(), sy = size.y(), sz = size.z();
    // Axis by axis: lines of n voxels `stride` apart, in blocks of `stride` lines side by
    // side; every voxel ORed with the voxels before and after it on its line (as they were
    // before this pass). Lines are independent, so they go to the threads.
    auto pass = [&](size_t blocks, size_t n, size_t stride) {
      ParallelFor(blocks * stride, threads, [&](size_t first, size_t last) {
        for (size_t line = first; line < last; ++line) {
          Bits* at = cells_.data() + (line / stride) * n * stride + line % stride;
          Bits before = 0;
          for (size_t k = 0; k < n; ++k, at += stride) {
            const Bits own = *at;
            const Bits after = k + 1 < n ? at[stride] : Bits{0};
            *at = static_cast<Bits>(before | own | after);
            before = own;
          }
        }
      });
    };
    pass(sy * sz, sx, 1);
    pass(sz, sy, sx);
    pass(1, sz, sx * sy);
  }
  // After Spread(); 0 outside the box.
  Bits At(const Eigen::Vector3d& point) const {
    const auto i = box_.Index(point);
    return i ? cells_[*i] : Bits{0};
  }

 private:
  VoxelBox box_;
  std::vector<Bits> cells_;
};

}  // namespace mirrorscan::reconstruction

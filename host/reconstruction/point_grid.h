#pragma once
// The decided peaks' points in their (column, frame) grid per camera, view and laser: each
// point's neighbours, found once, for the filters and the normals (docs/reconstruction.md,
// stages 6-7).
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// Output points with their place in the (column, frame) grid.
struct GridPoint {
  uint32_t peak = 0;
  Eigen::Vector3d point;
  Eigen::Vector3d last_direction;
  float sin_angle = 0;
  uint8_t key = 0;
  bool keep = true;
  // Flagged by the outlier test and left for the surface check to judge; never anyone's
  // neighbour.
  bool suspect = false;
};

class Grid {
 public:
  // A point per decided peak, in peak order.
  Grid(const PeakTable& table, const Hypotheses& hyp, int threads);

  // Finds every point's neighbours once: the point of the same (view, laser) at column
  // u + du in the frame df away whose row is nearest, within row_step (same frame) or
  // frame_step (another frame).
  void Link(double row_step, double frame_step, int threads);

  // That neighbour while it is kept and not suspect; -1 otherwise.
  int32_t Neighbour(const GridPoint& gp, int du, int df) const {
    const int32_t q = neighbours_[&gp - points.data()][Direction(du, df)];
    return q >= 0 && points[q].keep && !points[q].suspect ? q : -1;
  }

  std::vector<GridPoint> points;

 private:
  static int Direction(int du, int df) { return (df + 1) * 3 + du + 1; }
  int32_t Search(const GridPoint& gp, int du, int df, double max_dv) const;

  const PeakTable& table_;
  std::vector<int32_t> point_of_peak_;
  std::vector<int32_t> previous_frame_;
  std::vector<std::array<int32_t, 9>> neighbours_;
};

// How many kept columns follow this point in direction du before the stripe ends.
int RunLength(const Grid& grid, const GridPoint& gp, int du, int limit);

}  // namespace mirrorscan::reconstruction

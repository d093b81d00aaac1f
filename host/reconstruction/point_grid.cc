#include "host/reconstruction/point_grid.h"

#include <cmath>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {

Grid::Grid(const PeakTable& table, const Hypotheses& hyp, int threads) : table_(table) {
  point_of_peak_.assign(table.peaks.size(), -1);
  int32_t count = 0;
  for (uint32_t i = 0; i < table.peaks.size(); ++i)
    if (table.peaks[i].chosen >= 0) point_of_peak_[i] = count++;
  points.resize(count);
  ParallelFor(table.peaks.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      if (point_of_peak_[i] < 0) continue;
      const PeakState& p = table.peaks[i];
      const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
      points[point_of_peak_[i]] = {
          static_cast<uint32_t>(i), h.point, h.last_direction, h.sin_angle, h.key, true, false};
    }
  });
  previous_frame_.assign(table.next_frame.size(), -1);
  for (size_t f = 0; f < table.next_frame.size(); ++f)
    if (table.next_frame[f] >= 0) previous_frame_[table.next_frame[f]] = static_cast<int32_t>(f);
}

void Grid::Link(double row_step, double frame_step, int threads) {
  neighbours_.assign(points.size(), {});
  ParallelFor(points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      for (int df = -1; df <= 1; ++df)
        for (int du = -1; du <= 1; ++du)
          neighbours_[i][Direction(du, df)] =
              du == 0 && df == 0 ? -1 : Search(points[i], du, df, df == 0 ? row_step : frame_step);
    }
  });
}

int32_t Grid::Search(const GridPoint& gp, int du, int df, double max_dv) const {
  const PeakState& p = table_.peaks[gp.peak];
  int32_t frame = static_cast<int32_t>(p.frame);
  if (df > 0) frame = table_.next_frame[frame];
  if (df < 0) frame = previous_frame_[frame];
  if (frame < 0) return -1;
  const auto [lo, hi] = table_.Column(static_cast<uint32_t>(frame), p.u + du);
  int32_t best = -1;
  double best_dv = max_dv;
  for (uint32_t j = lo; j < hi; ++j) {
    const int32_t q = point_of_peak_[j];
    if (q < 0 || points[q].key != gp.key) continue;
    const double dv = std::abs(table_.peaks[j].v - p.v);
    if (dv <= best_dv) {
      best_dv = dv;
      best = q;
    }
  }
  return best;
}

int RunLength(const Grid& grid, const GridPoint& gp, int du, int limit) {
  int n = 0;
  const GridPoint* at = &gp;
  while (n < limit) {
    const int32_t q = grid.Neighbour(*at, du, 0);
    if (q < 0) break;
    at = &grid.points[q];
    ++n;
  }
  return n;
}

}  // namespace mirrorscan::reconstruction

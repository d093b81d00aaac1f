#pragma once

// Peaks against the virtual cabinet's truth CSV (`mirrorscan sim render` writes
// <camera>_frame<N>_truth.csv beside each image, `sim scan --truth` <camera>/truth.csv):
// frame,u,v,laser,view,x_mm,y_mm,z_mm,peak_dn, one row per column a stripe crosses.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "common/scan_format/peak.h"

namespace mirrorscan::test_support {

struct TruthRow {
  int frame = 0;
  int u = 0;
  double v = 0.0;
  int laser = 0;
};

// Rows of a truth CSV; throws if the file cannot be read or a row does not parse.
inline std::vector<TruthRow> ReadTruthCsv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  std::string line;
  std::getline(in, line);  // header
  std::vector<TruthRow> rows;
  while (std::getline(in, line)) {
    TruthRow r;
    if (std::sscanf(line.c_str(), "%d,%d,%lf,%d", &r.frame, &r.u, &r.v, &r.laser) != 4)
      throw std::runtime_error(file.string() + ": bad row: " + line);
    rows.push_back(r);
  }
  return rows;
}

// How a frame's peaks meet its truth: a truth point is found when a peak in its column
// lies within `tolerance_px` of it (the nearest such peak is its error); a peak no truth
// point of its column is that near to is a false peak.
struct PeakMatch {
  size_t truth = 0, found = 0, peaks = 0, false_peaks = 0;
  double sum_squared_px = 0.0, max_px = 0.0;

  double Recall() const { return truth ? static_cast<double>(found) / truth : 0.0; }
  double RmsPx() const { return found ? std::sqrt(sum_squared_px / found) : 0.0; }
  PeakMatch& operator+=(const PeakMatch& o) {
    truth += o.truth, found += o.found, peaks += o.peaks, false_peaks += o.false_peaks;
    sum_squared_px += o.sum_squared_px, max_px = std::max(max_px, o.max_px);
    return *this;
  }
};

inline PeakMatch MatchPeaks(const std::vector<Peak>& peaks, const std::vector<TruthRow>& truth,
                            double tolerance_px = 1.0) {
  std::multimap<int, double> truth_by_column, peaks_by_column;
  for (const TruthRow& t : truth) truth_by_column.emplace(t.u, t.v);
  for (const Peak& p : peaks) peaks_by_column.emplace(p.u, p.v);
  auto nearest = [](const std::multimap<int, double>& by_column, int u, double v) {
    double best = 1e9;
    const auto [first, last] = by_column.equal_range(u);
    for (auto it = first; it != last; ++it) best = std::min(best, std::abs(it->second - v));
    return best;
  };
  PeakMatch m;
  m.truth = truth.size();
  m.peaks = peaks.size();
  for (const TruthRow& t : truth) {
    const double error = nearest(peaks_by_column, t.u, t.v);
    if (error > tolerance_px) continue;
    ++m.found;
    m.sum_squared_px += error * error;
    m.max_px = std::max(m.max_px, error);
  }
  for (const Peak& p : peaks) {
    if (nearest(truth_by_column, p.u, p.v) > tolerance_px) ++m.false_peaks;
  }
  return m;
}

}  // namespace mirrorscan::test_support

#pragma once

// Shared between the SIMD and scalar candidate searches (not a public header).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/peaks/peaks.h"

namespace mirrorscan {
namespace peaks_internal {

using Candidate = PeakExtractor::Candidate;

// The candidate rule of peaks.h, on the ROI [x0, x1) x [y0, y1).
struct CandidateSearch {
  const uint8_t* data;
  ptrdiff_t stride;
  int x0, x1, y0, y1;
  int window;
  int threshold;

  int Clamp(int r) const { return std::clamp(r, y0, y1 - 1); }
  int At(int u, int r) const { return data[static_cast<ptrdiff_t>(Clamp(r)) * stride + u]; }
  static int Avg(int a, int b) { return (a + b + 1) >> 1; }
  int Mean4(int u, int r) const {
    return Avg(Avg(At(u, r), At(u, r + 1)), Avg(At(u, r + 2), At(u, r + 3)));
  }
  bool IsCandidate(int u, int r) const {
    const int c = At(u, r);
    if (!(At(u, r - 1) < c && At(u, r + 1) <= c)) return false;
    const int bg = std::min(Mean4(u, r - window), Mean4(u, r + window - 3));
    return c - bg >= threshold;
  }
};

// Appends each row's candidates to `row` (ascending u), then calls on_row(ctx), which
// consumes and clears them; rows in increasing order.
using RowCallback = void (*)(void* ctx);
void FindCandidatesSimd(const CandidateSearch& s, std::vector<Candidate>* row, RowCallback on_row,
                        void* ctx);
std::string SimdTargetName();

}  // namespace peaks_internal
}  // namespace mirrorscan

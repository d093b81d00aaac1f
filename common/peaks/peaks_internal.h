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
using SimdScratch = PeakExtractor::SimdScratch;

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
    // Over five rows: a maximum of the noise on a wide stripe's top or shoulder within two
    // rows of a brighter sample is no stripe of its own (a second stripe there would be
    // closer than any min_separation_px keeps), and refining it cost most of the time on
    // wide frames.
    if (!(At(u, r - 2) < c && At(u, r + 2) <= c)) return false;
    const int upper = Mean4(u, r - window), lower = Mean4(u, r + window - 3);
    if (c - std::min(upper, lower) < threshold) return false;
    return !NeverHalfHeight(u, r, upper, lower);
  }
  // The step rule. Most candidates (two thirds on rendered frames) are local maxima on the
  // bright side of an ambient step, which the refinement rejects because the column never
  // falls to half the peak's height above the background on that side within the window.
  // True where that is certain: a single top (a plateau moves the refinement's window),
  // flank means that prove a step (StepDn: the refinement then takes the lower flank as
  // the background), and every row on one side, out to the window, with 2 I > c + bg
  // (bg = the lower rounded flank mean, at least the refinement's background; the
  // refinement needs a row with 2 I <= c + background there). Out of line: only
  // candidates reach it.
  bool NeverHalfHeight(int u, int r, int upper, int lower) const;
  // Rounded flank means this far apart (2 |A_l - A_r| >= threshold + 3) prove that the
  // exact means differ by more than threshold / 2: each rounded mean is 0 ... 1 above the
  // exact one.
  static int StepDn(int threshold) { return (threshold + 4) / 2; }
};

// Appends each row's candidates to `row` (ascending u), then calls on_row(ctx), which
// consumes and clears them; rows in increasing order. `scratch` is reused across frames.
using RowCallback = void (*)(void* ctx);
void FindCandidatesSimd(const CandidateSearch& s, SimdScratch* scratch, std::vector<Candidate>* row,
                        RowCallback on_row, void* ctx);
std::string SimdTargetName();

}  // namespace peaks_internal
}  // namespace mirrorscan

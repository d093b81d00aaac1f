#pragma once

// Column-wise laser peak extraction: for every image column, the sub-pixel row of every
// laser stripe crossing it (several per column: up to 3 lasers x 3 views).
//
// Two stages, shared by both implementations:
//  1. Candidates (integer rows). Row r of column u is a candidate when it starts a local
//     maximum over five rows (I[r-2], I[r-1] < I[r] >= I[r+1], I[r+2]) and rises at least
//     threshold_dn above the local background b(r) = min(A(r-W .. r-W+3), A(r+W-3 .. r+W)), where
//     A(a..a+3) is the rounded 4-row mean avg(avg(I[a], I[a+1]), avg(I[a+2], I[a+3])) with avg(x,
//     y) = (x + y + 1) >> 1 and W = window. Rows outside the ROI are clamped to it. The step rule
//     drops a single top (I[r+1] < I[r]) whose flank means prove an ambient step (2 |A_l - A_r| >=
//     threshold_dn + 3) when every row on one side, out to W, has 2 I > I[r] + b(r): the refinement
//     would find no half-maximum crossing there, so this only saves its work (on rendered frames it
//     dropped 57 % of the candidates before the five-row rule). ExtractPeaks computes this with
//     SIMD over rows (many columns per vector); ExtractPeaksScalar walks each column. Both give the
//     same candidates.
//  2. Refinement (scalar, per candidate, identical in both): plateau, local linear
//     background from the two flanks, FWHM, width checks, sub-pixel estimator, score (at
//     most 0.1 for a line across an edge of reflectance, whose centre the edge moves);
//     then per column: min_separation_px (keep the stronger) and max_peaks_per_column
//     (keep the strongest).
//  3. Across columns (shared, so SIMD and scalar agree): each peak is linked to its stripe's peaks
//  in the columns
//     beside it; isolated peaks, faded stripe ends and dim peaks on short stripes are dropped
//     (drop_isolated_peaks, stripe_end_min_ratio, dim_peak_dn), and each row is smoothed along its
//     stripe (along_stripe_half_width).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/config/json_reader.h"
#include "common/scan_format/peak.h"

namespace mirrorscan {

// A borrowed 8-bit grayscale image; stride in bytes (>= width).
struct ImageView {
  const uint8_t* data = nullptr;
  int width = 0, height = 0;
  ptrdiff_t stride = 0;
};

// Sub-pixel estimators, each a pure function of the background-subtracted column samples
// around the candidate.
// Saturated tops and flat plateaus (>= 3 equal samples) always use the windowed centre of
// mass of the whole peak (flanks and plateau): a 3-point fit on clipped samples is wrong.
enum class PeakEstimator {
  kThresholdedCom,  // The paper: intensity-weighted mean row of the bright pixels (raw).
  kWindowedCom,     // Centre of mass of background-subtracted samples, window ~ +-2.7 sigma.
  kGaussian3,       // 3-point Gaussian (parabola through the logarithms).
  kBlaisRioux4,     // Blais-Rioux 4th-order derivative filter, linear zero crossing.
  kParabola3,       // 3-point parabola.
  // gaussian3 on sharp stripes; on wide ones (FWHM >= kWideStripeFwhmPx) a centre of mass
  // over +-kWideWindowSigmas sigma of the measured width, recentred on its own estimate, on
  // a background measured beyond the stripe (see peaks.cc, WideCentre).
  kAdaptive,
};
// Where `adaptive` leaves gaussian3 (chosen by measurement, docs/peak-extraction.md).
constexpr float kWideStripeFwhmPx = 3.0f;
constexpr float kWideWindowSigmas = 2.0f;
const char* ToString(PeakEstimator e);
const std::vector<PeakEstimator>& AllPeakEstimators();

// Along-stripe smoothing. A stripe is a continuous curve over u, and each column's row
// carries independent noise, so fitting the rows of neighbouring columns of the same
// stripe lowers the noise below what one column allows. With half width m >= 2, each
// peak's row becomes the centre value of the least-squares quadratic (Savitzky-Golay)
// through the rows of the 2m + 1 columns u - m .. u + m of its stripe: no bias on
// straight, slanted or curved (quadratic) stripes; noise x 0.70 / 0.58 / 0.51 / 0.46 for
// m = 2 / 3 / 4 / 5. The stripe is followed, not a fixed row window: the neighbour in
// column u +- 1 is the peak there nearest to this one's row, if within 1.5 px or their
// half-maximum extents overlap; the one in u +- 2 is the neighbour's neighbour, and so
// on. A pair u +- k is used only if both sides are linked and each continues its side's
// local trend (|second difference of three consecutive rows| <= 0.75 px); otherwise the
// fit shrinks to the pairs before it, and with fewer than 2 pairs (stripe ends, gaps,
// steps at depth discontinuities, kinks) the row is the column's own.
constexpr int kMaxAlongStripeHalfWidth = 8;

struct PixelRect {
  int x = 0, y = 0, width = 0, height = 0;  // width/height 0 in `roi` = to the frame edge.
  bool Contains(int u, int v) const { return u >= x && u < x + width && v >= y && v < y + height; }
};

struct PeakParams {
  PeakEstimator estimator = PeakEstimator::kAdaptive;
  int threshold_dn = 18;      // Peak minus local background, DN.
  int window = 8;             // Half-width in rows of the background/estimator window.
  float min_width_px = 1.2f;  // FWHM limits; narrower = glint, wider = not a laser line.
  float max_width_px = 8.0f;
  int max_peaks_per_column = 9;  // Keeps the strongest.
  float min_separation_px = 3.0f;
  int saturation_level = 255;       // Samples >= this are clipped.
  PixelRect roi;                    // Default: whole frame.
  std::vector<PixelRect> excluded;  // Peaks whose pixel falls in one of these are dropped.
  int along_stripe_half_width = 5;  // 0 or 1: off; see kMaxAlongStripeHalfWidth.
  // A peak with no stripe neighbour in either column beside it is dropped.
  bool drop_isolated_peaks = true;
  // A stripe's end peak (a neighbour on one side only) is dropped if its amplitude is
  // below this fraction of that neighbour's; 0 keeps every end.
  float stripe_end_min_ratio = 0.5f;
  // Dim stripes: a peak whose amplitude is under dim_peak_dn is kept only on a stripe of at
  // least dim_stripe_min_columns linked peaks, so the threshold can sit near the noise (a
  // mirror's view of a back lit at a grazing angle holds 10-17 DN) without letting noise
  // peaks through. dim_stripe_min_columns 0 or 1, or dim_peak_dn <= threshold_dn: off.
  int dim_peak_dn = 0;
  int dim_stripe_min_columns = 0;

  // Throws std::invalid_argument "peaks.<key>: problem" on bad values.
  void Validate() const;
  // Reads board.json's "peaks" object (all keys optional, unknown keys rejected):
  // {"estimator": "adaptive", "threshold_dn": 18, "window": 8, "min_width_px": 1.2,
  //  "max_width_px": 8, "max_peaks_per_column": 9, "min_separation_px": 3,
  //  "saturation_level": 255, "roi": {"x":0,"y":0,"width":0,"height":0},
  //  "excluded": [{"x":..,"y":..,"width":..,"height":..}, ...],
  //  "along_stripe_half_width": 5, "drop_isolated_peaks": true, "stripe_end_min_ratio": 0.5,
  //  "dim_peak_dn": 0, "dim_stripe_min_columns": 0}
  // Errors are ConfigError "file: peaks.key: problem".
  static PeakParams FromJson(const JsonReader& json);
};

// Reusable per-frame state: after the first frames, extraction allocates nothing.
class PeakExtractor {
 public:
  // SIMD candidates (Highway, runtime dispatch). `out` is cleared, then filled sorted by
  // (u, v).
  void Extract(const ImageView& image, const PeakParams& params, std::vector<Peak>* out);
  // Plain scalar reference, column by column; same peaks as Extract.
  void ExtractScalar(const ImageView& image, const PeakParams& params, std::vector<Peak>* out);

  // Highway target used by Extract (e.g. "AVX3", "AVX2", "NEON", "SVE2").
  static std::string SimdTarget();

  struct Candidate {
    uint16_t u;
    uint16_t v;
  };
  // The SIMD candidate pass's buffers, reused across frames.
  struct SimdScratch {
    std::vector<uint8_t> means;  // A ring of rows' flank means.
  };

 private:
  void Run(const ImageView& image, const PeakParams& params, bool simd, std::vector<Peak>* out);
  static void RefineRow(void* ctx);

  std::vector<Candidate> candidates_;  // Of one row (SIMD) or one column (scalar).
  SimdScratch simd_scratch_;
  std::vector<Peak> peaks_;  // Refined, before the per-column pass.
  std::vector<uint32_t> column_start_;
  std::vector<float> rows_;     // Unsmoothed rows, while smoothing along the stripe.
  std::vector<int32_t> links_;  // Each peak's neighbours along its stripe.
  std::vector<uint8_t> dropped_;
  std::vector<uint8_t> extent_;  // How far each peak's stripe goes on, per side.
  std::vector<int32_t> stripe_;  // Union-find roots and sizes of the stripes (dim peaks).
};

// The fair reference for speed and accuracy: a plain thresholded centre of mass, as one
// would write it without tuning — one pass over the rows, a running sum per column, no
// SIMD. A run of samples above `threshold_dn` in a column is one stripe; its row is the
// mean row weighted by (I - threshold_dn), width the run's length, intensity its top above
// the threshold. No background model, no width or shape checks. Peaks come in the order
// their runs end (by row, then column). Reuses its buffers across frames.
class PlainCentreOfMass {
 public:
  void Extract(const ImageView& image, int threshold_dn, std::vector<Peak>* out);

 private:
  std::vector<uint32_t> sum_, moment_;
  std::vector<uint16_t> first_, top_;
};

std::vector<Peak> ExtractPeaks(const ImageView& image, const PeakParams& params);
void ExtractPeaks(const ImageView& image, const PeakParams& params, PeakExtractor* extractor,
                  std::vector<Peak>* out);
std::vector<Peak> ExtractPeaksScalar(const ImageView& image, const PeakParams& params);

}  // namespace mirrorscan

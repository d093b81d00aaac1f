#include "common/peaks/peaks.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include "common/peaks/peaks_internal.h"

namespace mirrorscan {
namespace {

using peaks_internal::Candidate;
using peaks_internal::CandidateSearch;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct NamedEstimator {
  PeakEstimator estimator;
  const char* name;
};
constexpr NamedEstimator kEstimatorNames[] = {
    {PeakEstimator::kThresholdedCom, "thresholded_com"},
    {PeakEstimator::kWindowedCom, "windowed_com"},
    {PeakEstimator::kGaussian3, "gaussian3"},
    {PeakEstimator::kBlaisRioux4, "blais_rioux4"},
    {PeakEstimator::kParabola3, "parabola3"},
    {PeakEstimator::kAdaptive, "adaptive"},
};

// Column profile around one candidate, in sample coordinates (index i = row lo + i),
// read on demand straight from the image column.
struct Profile {
  const uint8_t* col;  // Row lo of the column.
  ptrdiff_t stride;
  float b0, slope;  // Background at sample i: b0 + slope * i.
  int n;
  int first, last;     // Plateau (first == last unless the top is flat).
  int win_lo, win_hi;  // Estimator window (inclusive), valley-clipped.
  float threshold;
  bool flat_top;  // Saturated or a plateau of >= 3 samples: no 3-point fit.
  float Raw(int i) const { return static_cast<float>(col[i * stride]); }
  // Background-subtracted sample.
  float S(int i) const { return Raw(i) - (b0 + slope * static_cast<float>(i)); }
};

template <bool kRaw>
float CentreOfMass(const Profile& p, int lo, int hi) {
  float sum = 0, moment = 0;
  for (int i = lo; i <= hi; ++i) {
    const float wi = kRaw ? p.Raw(i) : std::max(0.0f, p.S(i));
    sum += wi;
    moment += wi * static_cast<float>(i - lo);
  }
  return sum > 0 ? static_cast<float>(lo) + moment / sum : kNaN;
}

float WindowedCom(const Profile& p) { return CentreOfMass<false>(p, p.win_lo, p.win_hi); }

// The paper: intensity-weighted mean row of the contiguous bright pixels (raw weights).
float ThresholdedCom(const Profile& p) {
  int lo = p.first, hi = p.last;
  while (lo > p.win_lo && p.S(lo - 1) >= p.threshold) --lo;
  while (hi < p.win_hi && p.S(hi + 1) >= p.threshold) ++hi;
  return CentreOfMass<true>(p, lo, hi);
}

float Parabola3(const Profile& p) {
  const int k = p.first;
  if (k < 1 || k + 1 >= p.n) return kNaN;
  const float a = p.S(k - 1), b = p.S(k), c = p.S(k + 1);
  const float den = a - 2 * b + c;
  if (!(den < 0)) return kNaN;
  return k + 0.5f * (a - c) / den;
}

float Gaussian3(const Profile& p) {
  const int k = p.first;
  if (k < 1 || k + 1 >= p.n) return kNaN;
  const float a = p.S(k - 1), b = p.S(k), c = p.S(k + 1);
  if (!(a > 0 && b > 0 && c > 0)) return Parabola3(p);
  // ln a - 2 ln b + ln c = ln(a c / b^2); ln a - ln c = ln(a / c).
  const float den = std::log((a * c) / (b * b));
  if (!(den < 0)) return kNaN;
  return static_cast<float>(k) + 0.5f * std::log(a / c) / den;
}

float BlaisRioux4(const Profile& p) {
  const int k = p.first;
  if (k < 3 || k + 3 >= p.n) return kNaN;
  auto g = [&](int i) { return p.S(i + 2) + p.S(i + 1) - p.S(i - 1) - p.S(i - 2); };
  // g > 0 left of the peak, < 0 right of it; interpolate the zero crossing.
  const float g0 = g(k);
  if (g0 >= 0) {
    const float g1 = g(k + 1);
    if (!(g1 < 0)) return kNaN;
    return k + g0 / (g0 - g1);
  }
  const float gm = g(k - 1);
  if (!(gm > 0)) return kNaN;
  return (k - 1) + gm / (gm - g0);
}

float Estimate(PeakEstimator e, const Profile& p) {
  if (p.flat_top) return WindowedCom(p);  // Clipped: no fit on the plateau.
  switch (e) {
    case PeakEstimator::kThresholdedCom:
      return ThresholdedCom(p);
    case PeakEstimator::kWindowedCom:
      return WindowedCom(p);
    case PeakEstimator::kGaussian3:
    case PeakEstimator::kAdaptive:  // sharp stripes; wide ones take WideCentre
      return Gaussian3(p);
    case PeakEstimator::kBlaisRioux4:
      return BlaisRioux4(p);
    case PeakEstimator::kParabola3:
      return Parabola3(p);
  }
  return kNaN;
}

[[noreturn]] void Invalid(const std::string& key, const std::string& problem) {
  throw std::invalid_argument("peaks." + key + ": " + problem);
}

struct Roi {
  int x0, x1, y0, y1;
};

Roi ResolveRoi(const ImageView& image, const PixelRect& roi) {
  const int w = roi.width > 0 ? roi.width : image.width - roi.x;
  const int h = roi.height > 0 ? roi.height : image.height - roi.y;
  Roi r{roi.x, roi.x + w, roi.y, roi.y + h};
  r.x0 = std::clamp(r.x0, 0, image.width);
  r.x1 = std::clamp(r.x1, r.x0, image.width);
  r.y0 = std::clamp(r.y0, 0, image.height);
  r.y1 = std::clamp(r.y1, r.y0, image.height);
  return r;
}

void CheckImage(const ImageView& image) {
  if (image.width < 0 || image.height < 0 || image.width > 65535 || image.height > 65535 ||
      (image.width > 0 && image.height > 0 &&
       (image.data == nullptr || image.stride < image.width))) {
    throw std::invalid_argument("ExtractPeaks: bad image view");
  }
}

CandidateSearch MakeSearch(const ImageView& image, const PeakParams& params, const Roi& roi) {
  return CandidateSearch{image.data, image.stride, roi.x0,        roi.x1,
                         roi.y0,     roi.y1,       params.window, params.threshold_dn};
}

}  // namespace

const char* ToString(PeakEstimator e) {
  for (const auto& n : kEstimatorNames)
    if (n.estimator == e) return n.name;
  return "?";
}

const std::vector<PeakEstimator>& AllPeakEstimators() {
  static const std::vector<PeakEstimator> all = {
      PeakEstimator::kThresholdedCom, PeakEstimator::kWindowedCom, PeakEstimator::kGaussian3,
      PeakEstimator::kBlaisRioux4,    PeakEstimator::kParabola3,   PeakEstimator::kAdaptive};
  return all;
}

void PeakParams::Validate() const {
  if (threshold_dn < 1 || threshold_dn > 254) Invalid("threshold_dn", "must be in [1, 254]");
  if (window < 4 || window > 64) Invalid("window", "must be in [4, 64]");
  if (!(min_width_px >= 0) || !std::isfinite(min_width_px)) {
    Invalid("min_width_px", "must be >= 0");
  }
  if (!(max_width_px > min_width_px) || !std::isfinite(max_width_px)) {
    Invalid("max_width_px", "must be > min_width_px");
  }
  if (max_width_px > 2 * window) Invalid("max_width_px", "must be <= 2 * window");
  if (max_peaks_per_column < 1 || max_peaks_per_column > 64) {
    Invalid("max_peaks_per_column", "must be in [1, 64]");
  }
  if (!(min_separation_px >= 0) || !std::isfinite(min_separation_px)) {
    Invalid("min_separation_px", "must be >= 0");
  }
  if (saturation_level < 1 || saturation_level > 255) {
    Invalid("saturation_level", "must be in [1, 255]");
  }
  if (roi.x < 0 || roi.y < 0 || roi.width < 0 || roi.height < 0) {
    Invalid("roi", "x, y, width, height must be >= 0");
  }
  if (along_stripe_half_width < 0 || along_stripe_half_width > kMaxAlongStripeHalfWidth) {
    Invalid("along_stripe_half_width",
            "must be in [0, " + std::to_string(kMaxAlongStripeHalfWidth) + "]");
  }
  if (!(stripe_end_min_ratio >= 0 && stripe_end_min_ratio <= 1)) {
    Invalid("stripe_end_min_ratio", "must be in [0, 1]");
  }
  if (dim_peak_dn < 0 || dim_peak_dn > 255) Invalid("dim_peak_dn", "must be in [0, 255]");
  if (dim_stripe_min_columns < 0 || dim_stripe_min_columns > 64) {
    Invalid("dim_stripe_min_columns", "must be in [0, 64]");
  }
  for (size_t i = 0; i < excluded.size(); ++i) {
    const PixelRect& e = excluded[i];
    if (e.x < 0 || e.y < 0 || e.width <= 0 || e.height <= 0) {
      Invalid("excluded[" + std::to_string(i) + "]", "x, y must be >= 0, width, height > 0");
    }
  }
}

PeakParams PeakParams::FromJson(const JsonReader& json) {
  json.AllowOnly({"estimator", "threshold_dn", "window", "min_width_px", "max_width_px",
                  "max_peaks_per_column", "min_separation_px", "saturation_level", "roi",
                  "excluded", "along_stripe_half_width", "drop_isolated_peaks",
                  "stripe_end_min_ratio", "dim_peak_dn", "dim_stripe_min_columns"});
  PeakParams p;
  std::vector<std::string> names;
  for (const auto& n : kEstimatorNames) names.push_back(n.name);
  const std::string estimator = json.Choice("estimator", names, ToString(p.estimator));
  for (const auto& n : kEstimatorNames)
    if (estimator == n.name) p.estimator = n.estimator;
  p.threshold_dn = json.Integer("threshold_dn", p.threshold_dn, 1, 254);
  p.window = json.Integer("window", p.window, 4, 64);
  p.min_width_px = static_cast<float>(json.Number("min_width_px", p.min_width_px, 0, 128));
  p.max_width_px = static_cast<float>(json.Number("max_width_px", p.max_width_px, 0, 128));
  if (p.max_width_px <= p.min_width_px) json.Fail("max_width_px", "must be > min_width_px");
  if (p.max_width_px > 2 * p.window) json.Fail("max_width_px", "must be <= 2 * window");
  p.max_peaks_per_column = json.Integer("max_peaks_per_column", p.max_peaks_per_column, 1, 64);
  p.min_separation_px =
      static_cast<float>(json.Number("min_separation_px", p.min_separation_px, 0, 1000));
  p.saturation_level = json.Integer("saturation_level", p.saturation_level, 1, 255);
  auto rect = [](const JsonReader& r, bool positive) {
    r.AllowOnly({"x", "y", "width", "height"});
    PixelRect out;
    out.x = r.Integer("x", 0, 0, 65535);
    out.y = r.Integer("y", 0, 0, 65535);
    out.width =
        positive ? r.Integer("width", std::nullopt, 1, 65535) : r.Integer("width", 0, 0, 65535);
    out.height =
        positive ? r.Integer("height", std::nullopt, 1, 65535) : r.Integer("height", 0, 0, 65535);
    return out;
  };
  if (json.Has("roi")) p.roi = rect(json.Object("roi"), false);
  if (json.Has("excluded")) {
    for (const JsonReader& r : json.Objects("excluded")) p.excluded.push_back(rect(r, true));
  }
  p.along_stripe_half_width = json.Integer("along_stripe_half_width", p.along_stripe_half_width, 0,
                                           kMaxAlongStripeHalfWidth);
  p.drop_isolated_peaks = json.Bool("drop_isolated_peaks", p.drop_isolated_peaks);
  p.stripe_end_min_ratio =
      static_cast<float>(json.Number("stripe_end_min_ratio", p.stripe_end_min_ratio, 0, 1));
  p.dim_peak_dn = json.Integer("dim_peak_dn", p.dim_peak_dn, 0, 255);
  p.dim_stripe_min_columns =
      json.Integer("dim_stripe_min_columns", p.dim_stripe_min_columns, 0, 64);
  try {
    p.Validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(json.file() + ": " + e.what());
  }
  return p;
}

std::string PeakExtractor::SimdTarget() { return peaks_internal::SimdTargetName(); }

bool peaks_internal::CandidateSearch::NeverHalfHeight(int u, int r, int upper, int lower) const {
  const int c = At(u, r);
  if (std::abs(upper - lower) < StepDn(threshold) || At(u, r + 1) == c) return false;
  int low_up = c, low_dn = c;
  for (int k = 1; k <= window; ++k) {
    low_up = std::min(low_up, At(u, r - k));
    low_dn = std::min(low_dn, At(u, r + k));
  }
  const int bg = std::min(upper, lower);
  return 2 * low_up > c + bg || 2 * low_dn > c + bg;
}

namespace {

// Half-maximum crossings left and right of the top [first, last], linearly interpolated;
// false if a crossing is not inside the samples.
template <typename S>
bool HalfMaxCrossings(const S& s, int first, int last, int n, float half, float* xl, float* xr) {
  int il = first;
  float s_in = s(il), s_out = s(il - 1);  // first >= 1: candidates are never on row y0.
  while (s_out > half) {
    if (--il == 0) return false;
    s_in = s_out;
    s_out = s(il - 1);
  }
  *xl = static_cast<float>(il - 1) + (half - s_out) / (s_in - s_out);
  int ir = last;
  if (ir >= n - 1) return false;
  s_in = s(ir);
  s_out = s(ir + 1);
  while (s_out > half) {
    if (++ir == n - 1) return false;
    s_in = s_out;
    s_out = s(ir + 1);
  }
  *xr = static_cast<float>(ir) + (s_in - half) / (s_in - s_out);
  return true;
}

// The row of a wide stripe (FWHM `width` >= kWideStripeFwhmPx, top rows [r0, r1]) in column
// u. A 3-point fit reads 3 samples of a profile 6 px wide, so its noise grows with the
// square of the width; this reads the whole profile. The window's flanks (W rows out) still
// hold the tails of a wide stripe, so the background is measured again beyond its reach:
// 3-row means from 3 sigma + 1 out, linear through both; NaN (take the 3-point fit) if
// they disagree by more than threshold/2 (a neighbouring line, an ambient step). Then the
// background-subtracted centre of mass over +-kWideWindowSigmas sigma, the window recentred on its
// own estimate until it settles (a window centred on the integer top would pull the estimate
// towards it), its end pixels weighted by the part of them inside.
float WideCentre(const CandidateSearch& search, int u, int r0, int r1, float width, float thr,
                 float start) {
  const float sigma = width * (1.0f / 2.3548f);
  const int reach = static_cast<int>(std::ceil(3.0f * sigma)) + 1;
  // The column's samples from the left background's first row to the right one's last, read
  // once (the passes below reread them): rows lo_row + i.
  constexpr int kMaxSamples = 96;
  const int lo_row = r0 - reach - 2, hi_row = r1 + reach + 2;
  const int count = hi_row - lo_row + 1;
  if (count > kMaxSamples) return kNaN;
  float sample[kMaxSamples];
  if (lo_row >= search.y0 && hi_row < search.y1) {
    const uint8_t* col = search.data + static_cast<ptrdiff_t>(lo_row) * search.stride + u;
    for (int i = 0; i < count; ++i) sample[i] = static_cast<float>(col[i * search.stride]);
  } else {
    for (int i = 0; i < count; ++i) sample[i] = static_cast<float>(search.At(u, lo_row + i));
  }
  const float left = (sample[0] + sample[1] + sample[2]) * (1.0f / 3.0f);
  const float right = (sample[count - 3] + sample[count - 2] + sample[count - 1]) * (1.0f / 3.0f);
  // Flanks that disagree mean a neighbouring line or an ambient step within the wide
  // support: the 3-point fit, which reads only the top, is the safer estimate there.
  if (std::abs(left - right) > 0.5f * thr) return kNaN;
  // Background-subtracted samples, in coordinates x = row - lo_row (means centred on x = 1
  // and count - 2).
  const float slope = (right - left) / static_cast<float>(count - 3);
  for (int i = 0; i < count; ++i) sample[i] -= left + slope * static_cast<float>(i - 1);
  // Within a pixel the light is taken as linear, s + g x with the slope g = (s[i + 1] -
  // s[i - 1]) / 2 of its neighbours, so a partly covered end pixel counts the light of its
  // covered part; a whole pixel i holds mass s and moment i s + g / 12. Samples <= 0 count
  // nothing. The part [x0, x1] of pixel i inside the window (relative to its centre):
  auto partial = [&](int i, float x0, float x1, float* mass, float* moment) {
    const float si = sample[i];
    if (!(x1 > x0) || !(si > 0)) return;
    const float g = 0.5f * (sample[i + 1] - sample[i - 1]);
    const float p1 = 0.5f * (x1 * x1 - x0 * x0), p2 = (x1 * x1 * x1 - x0 * x0 * x0) * (1.0f / 3.0f);
    const float m = si * (x1 - x0) + g * p1;
    *mass += m;
    *moment += static_cast<float>(i) * m + si * p1 + g * p2;
  };
  const float half = kWideWindowSigmas * sigma;
  // Each pass moves the window to its own centre of mass m(c). Its fixed point m(c) = c is
  // the estimate; near it m(c) - c* ~ k (c - c*) with k = 2h phi(h) / (2 Phi(h) - 1) = 0.226
  // for a Gaussian at h = 2 sigma (each plain pass leaves ~0.23 of the offset). So each pass
  // steps by (m(c) - c) / (1 - k), which lands on the fixed point up to the profile's
  // departure from that slope: ~2 passes from the middle of the half-maximum crossings
  // (within a few hundredths of a pixel), where plain recentring took 4.4 on average to move
  // by less than 1e-3 px. It stops when a step is under kWideSettledPx.
  constexpr float kStep = 1.0f / (1.0f - 0.2263f);
  constexpr float kWideSettledPx = 5e-3f;
  float centre = start - static_cast<float>(lo_row);
  int whole_first = -1, whole_last = -1;
  float whole_mass = 0, whole_moment = 0;
  for (int pass = 0; pass < 8; ++pass) {
    const float a = centre - half, b = centre + half;
    const int first = static_cast<int>(std::floor(a + 0.5f));
    const int last = static_cast<int>(std::ceil(b - 0.5f));
    if (first < 1 || last > count - 2 || last - first < 2) return kNaN;
    // Whole pixels first + 1 .. last - 1 (the same as the last pass's but where the window
    // crossed a pixel boundary: summed again only then), in two interleaved sums each, then
    // the two end pixels' covered parts.
    if (first != whole_first || last != whole_last) {
      whole_first = first;
      whole_last = last;
      float mass2[2] = {0, 0}, moment2[2] = {0, 0};
      for (int i = first + 1; i < last; ++i) {
        const float si = sample[i];
        const float lit = si > 0 ? 1.0f : 0.0f;
        mass2[i & 1] += lit * si;
        moment2[i & 1] +=
            lit * (static_cast<float>(i) * si + (sample[i + 1] - sample[i - 1]) * (1.0f / 24.0f));
      }
      whole_mass = mass2[0] + mass2[1];
      whole_moment = moment2[0] + moment2[1];
    }
    float sum = whole_mass, moment = whole_moment;
    partial(first, std::max(-0.5f, a - static_cast<float>(first)), 0.5f, &sum, &moment);
    partial(last, -0.5f, std::min(0.5f, b - static_cast<float>(last)), &sum, &moment);
    if (!(sum > 0)) return kNaN;
    const float moved = kStep * (moment / sum - centre);
    centre += moved;
    if (std::abs(moved) < kWideSettledPx) break;
  }
  return centre + static_cast<float>(lo_row);
}

// A line across an edge of reflectance (dark underwear against skin, the body's outline
// against the dark cabinet) is dimmed on the edge's dark side, so its centre moves towards
// the bright side (up to 1.5 px for a sharp line at 6:1), and the body's outline cuts the
// line besides. No background model undoes that from one column, so such a peak is given
// with a score of at most kEdgeScore, for the host to judge against its neighbours (the
// reconstruction's surface check): where the flanks' ambient differs by kEdgeRatio or more
// and the edge runs through the line or near it. On the bright side the samples never
// fall back below kEdgeValley of the step (`bright_valley`, background-subtracted; a
// neighbouring line leaves a deeper valley, noise a shallower one), and on the dark side
// they reach the dark level (within 1 - kEdgeWithin of the step) within 3 sigma of the top
// plus 3 px. On the virtual cabinet's bodies these lines gave the points 5-15 mm off the
// surface, along the underwear's edges; dropping them instead emptied the slices below
// each hem, where the thigh girth is measured.
constexpr float kEdgeRatio = 2.5f;
constexpr float kEdgeWithin = 0.7f;
constexpr float kEdgeValley = 0.6f;
constexpr float kEdgeScore = 0.1f;
bool OnReflectanceEdge(const Profile& p, float left, float right, float width,
                       float bright_valley) {
  const float dark = std::min(left, right), bright = std::max(left, right);
  const float step = bright - dark;
  if (bright + 1.0f < kEdgeRatio * (dark + 1.0f)) return false;
  if (bright_valley < kEdgeValley * step) return false;
  const int reach = static_cast<int>(std::ceil(1.27f * width)) + 3;
  const float dark_level = dark + (1.0f - kEdgeWithin) * step;
  if (right > left) {  // Dark above: walk up from the top.
    for (int i = p.first - 1; i >= std::max(0, p.first - reach); --i)
      if (p.Raw(i) <= dark_level) return true;
  } else {
    for (int i = p.last + 1; i <= std::min(p.n - 1, p.last + reach); ++i)
      if (p.Raw(i) <= dark_level) return true;
  }
  return false;
}

// Refines one candidate (u, r0) into a peak; false if it is no laser peak. A pure function
// of the image and the candidate, so the order candidates arrive in does not matter.
bool RefineOne(const CandidateSearch& search, const PeakParams& params, int u, int r0, Peak* peak) {
  for (const PixelRect& e : params.excluded)
    if (e.Contains(u, r0)) return false;
  const int w = params.window;
  const float thr = static_cast<float>(params.threshold_dn);
  const ptrdiff_t stride = search.stride;
  const uint8_t* column = search.data + u;
  const int top = column[r0 * stride];
  // Plateau (flat top); a step up after it means this is no maximum.
  int r1 = r0;
  while (r1 + 1 < search.y1 && column[(r1 + 1) * stride] == top && r1 - r0 < 2 * w) ++r1;
  if (r1 + 1 < search.y1 && column[(r1 + 1) * stride] > top) return false;
  if (r1 - r0 >= 2 * w) return false;
  // Local background from the two flanks: linear if they agree, else the lower one
  // (the other may hold a neighbouring line).
  int left_sum = 0, right_sum = 0;
  if (r0 - w >= search.y0 && r1 + w < search.y1) {
    const uint8_t* l = column + (r0 - w) * stride;
    const uint8_t* r = column + (r1 + w - 3) * stride;
    left_sum = l[0] + l[stride] + l[2 * stride] + l[3 * stride];
    right_sum = r[0] + r[stride] + r[2 * stride] + r[3 * stride];
  } else {
    for (int k = 0; k < 4; ++k) {
      left_sum += search.At(u, r0 - w + k);
      right_sum += search.At(u, r1 + w - 3 + k);
    }
  }
  const float left = 0.25f * static_cast<float>(left_sum);
  const float right = 0.25f * static_cast<float>(right_sum);
  const float x_left = static_cast<float>(r0 - w) + 1.5f;
  const float x_right = static_cast<float>(r1 + w) - 1.5f;
  const bool linear = std::abs(left - right) <= 0.5f * thr;
  const float slope = linear ? (right - left) / (x_right - x_left) : 0.0f;
  const float base = linear ? left : std::min(left, right);
  const int lo = std::max(r0 - w, search.y0);
  const int hi = std::min(r1 + w, search.y1 - 1);
  const int n = hi - lo + 1;
  const int first = r0 - lo, last = r1 - lo;
  const bool saturated = top >= params.saturation_level;
  Profile profile{column + lo * stride,
                  stride,
                  base + (linear ? slope * (static_cast<float>(lo) - x_left) : 0.0f),
                  slope,
                  n,
                  first,
                  last,
                  first,
                  last,
                  thr,
                  saturated || last - first >= 2};
  auto s = [&profile](int i) { return profile.S(i); };
  const int mid = (first + last) / 2;
  const float amplitude = (first + last) % 2 == 0 ? s(mid) : 0.5f * (s(mid) + s(mid + 1));
  if (amplitude < thr) return false;
  // Full width at half maximum, linear interpolation of the crossings.
  const float half = 0.5f * amplitude;
  float xl, xr;
  if (!HalfMaxCrossings(s, first, last, n, half, &xl, &xr)) return false;
  const float width = xr - xl;
  // A clipped top's half-maximum width is that of its clipped amplitude, wider than the
  // stripe's FWHM: only the window bounds it.
  if (width < params.min_width_px ||
      width > (saturated ? 2.0f * static_cast<float>(w) : params.max_width_px)) {
    return false;
  }
  // A line stands out on both sides. The background is the lower flank (so a neighbouring
  // line does not hide this one), which also lets a noise spike on the bright side of an
  // ambient step pass as a peak of the step's height: on rendered frames at read noise
  // 5 DN those were ~99 % of all false peaks. So the top must also rise above the lowest
  // sample on each side, out to 1.5 FWHM beyond the half-maximum crossing (a neighbouring
  // line leaves a valley there, a step does not), by the threshold, or by 0.9 x the
  // amplitude for a peak barely above it (that minimum is noise-biased low, and an
  // isolated line falls to its background on both sides). Only needed where the flanks
  // disagree: with a linear background a step lifts both sides alike.
  bool on_edge = false;
  if (!linear) {
    const float top_s = std::max(s(first), s(last));
    const int reach = std::max(2, static_cast<int>(std::ceil(1.5f * width)));
    const int left_from = std::min(static_cast<int>(std::floor(xl)), first - 1);
    const int right_from = std::max(static_cast<int>(std::ceil(xr)), last + 1);
    float valley_left = top_s, valley_right = top_s;
    for (int i = left_from; i >= std::max(0, left_from - reach); --i)
      valley_left = std::min(valley_left, s(i));
    for (int i = right_from; i <= std::min(n - 1, right_from + reach); ++i)
      valley_right = std::min(valley_right, s(i));
    if (top_s - std::max(valley_left, valley_right) < std::min(thr, 0.9f * amplitude)) {
      return false;
    }
    on_edge =
        OnReflectanceEdge(profile, left, right, width, right > left ? valley_right : valley_left);
  }
  if (profile.flat_top || params.estimator == PeakEstimator::kWindowedCom ||
      params.estimator == PeakEstimator::kThresholdedCom) {
    // Estimator window: ~ +-2.7 sigma around the top, clipped where the signal rises
    // again (a neighbouring line) by more than the noise allowance.
    const int k = std::min(w, static_cast<int>(std::ceil(1.15f * width)));
    const float rise = 0.25f * thr + 0.05f * amplitude;
    int wl = first, wr = last;
    float low = s(wl);
    while (wl > 0 && wl > first - k) {
      const float next = s(wl - 1);
      if (next > low + rise) break;
      --wl;
      low = std::min(low, next);
    }
    low = s(wr);
    while (wr < n - 1 && wr < last + k) {
      const float next = s(wr + 1);
      if (next > low + rise) break;
      ++wr;
      low = std::min(low, next);
    }
    profile.win_lo = wl;
    profile.win_hi = wr;
  }
  float t = kNaN;
  if (params.estimator == PeakEstimator::kAdaptive && !profile.flat_top &&
      width >= kWideStripeFwhmPx) {
    t = WideCentre(search, u, r0, r1, width, thr, static_cast<float>(lo) + 0.5f * (xl + xr)) -
        static_cast<float>(lo);
  }
  if (!std::isfinite(t)) t = Estimate(params.estimator, profile);
  if (!std::isfinite(t) || t < static_cast<float>(first) - 1.5f ||
      t > static_cast<float>(last) + 1.5f) {
    return false;
  }
  peak->u = static_cast<uint16_t>(u);
  peak->v = static_cast<float>(lo) + t;
  peak->intensity = amplitude;
  peak->width = width;
  // Quality: contrast over threshold, width well inside the limits, symmetric
  // half-maximum crossings about the estimate, clipped tops are less certain.
  const float q_amp = amplitude / (amplitude + 2.0f * thr);
  const float q_wid = std::clamp((width - params.min_width_px) / 0.5f, 0.0f, 1.0f) *
                      std::clamp((params.max_width_px - width) / 1.0f, 0.0f, 1.0f);
  const float q_sym = std::clamp(1.0f - std::abs(xl + xr - 2.0f * t) / width, 0.0f, 1.0f);
  peak->score = std::clamp(q_amp * q_wid * q_sym * (saturated ? 0.8f : 1.0f), 0.0f, 1.0f);
  if (on_edge) peak->score = std::min(peak->score, kEdgeScore);
  return true;
}

bool ByRow(const Peak& a, const Peak& b) {
  if (a.v != b.v) return a.v < b.v;
  if (a.intensity != b.intensity) return a.intensity > b.intensity;
  return a.width < b.width;
}

bool ByStrength(const Peak& a, const Peak& b) {
  if (a.intensity != b.intensity) return a.intensity > b.intensity;
  return ByRow(a, b);
}

// Along-stripe smoothing (peaks.h, along_stripe_half_width).
constexpr float kLinkPx = 1.5f;   // A neighbour column's peak this close continues the stripe.
constexpr float kKinkPx = 0.75f;  // Max |second difference| of three consecutive rows.
// A wide stripe's end (FWHM >= kWideStripeFwhmPx) against the brightest of this many
// columns further in; at most kWideEndPeel columns of its fading end are dropped.
constexpr int kWideEndColumns = 3;
constexpr int kWideEndPeel = 4;

// Savitzky-Golay weights of the centre of a quadratic through 2m + 1 equally spaced
// samples: w_k = (3 (3m^2 + 3m - 1) - 15 k^2) / ((2m + 1)(4m^2 + 4m - 3)), k = 0 .. m.
struct QuadraticKernels {
  float w[kMaxAlongStripeHalfWidth + 1][kMaxAlongStripeHalfWidth + 1] = {};
  constexpr QuadraticKernels() {
    for (int m = 2; m <= kMaxAlongStripeHalfWidth; ++m) {
      const float den = static_cast<float>((2 * m + 1) * (4 * m * m + 4 * m - 3));
      for (int k = 0; k <= m; ++k) {
        w[m][k] = static_cast<float>(3 * (3 * m * m + 3 * m - 1) - 15 * k * k) / den;
      }
    }
  }
};
constexpr QuadraticKernels kQuadraticKernels;

// The pass across columns (stage 3 of peaks.h). `peaks` sorted by (u, v); column c
// (relative to the ROI at x0) holds [start[c], start[c + 1]); on return `peaks` and
// `start` hold what is kept. Every decision reads the rows, widths and amplitudes of
// stage 2 only, so the result does not depend on the order peaks are visited in.
void AlongStripePass(const PeakParams& params, int ncols, int x0, uint32_t* start,
                     std::vector<float>* rows, std::vector<int32_t>* links,
                     std::vector<uint8_t>* dropped, std::vector<uint8_t>* extent,
                     std::vector<int32_t>* stripe, std::vector<Peak>* peaks) {
  const int half_width = params.along_stripe_half_width;
  const float end_ratio = params.stripe_end_min_ratio;
  if (half_width < 2 && !params.drop_isolated_peaks && !(end_ratio > 0) &&
      params.dim_stripe_min_columns < 2) {
    return;
  }
  const size_t count = start[ncols];
  Peak* p = peaks->data();
  rows->resize(count);
  for (size_t i = 0; i < count; ++i) (*rows)[i] = p[i].v;
  const float* v = rows->data();
  // links[2i] / links[2i + 1]: the peak in the column left / right of peak i nearest to
  // its row, if their half-maximum extents overlap or they are within kLinkPx (so a steep
  // stripe, wide in its column, still links), else -1. Following links walks the stripe.
  links->resize(2 * count);
  int32_t* link = links->data();
  // Whether peak j is within `reach` times the link distance of peak i's row (reach 1 for
  // the column beside it, 2 across a one-column gap).
  auto within = [&](size_t i, uint32_t j, float reach) {
    return std::abs(v[j] - v[i]) <= reach * std::max(kLinkPx, 0.5f * (p[i].width + p[j].width));
  };
  // The peak in column `col` nearest to peak i's row, if within reach, else -1.
  auto nearest = [&](int col, size_t i, float reach) {
    if (col < 0 || col >= ncols || start[col] == start[col + 1]) return int32_t{-1};
    uint32_t best = start[col];
    for (uint32_t j = best + 1; j < start[col + 1]; ++j)
      if (std::abs(v[j] - v[i]) < std::abs(v[best] - v[i])) best = j;
    return within(i, best, reach) ? static_cast<int32_t>(best) : int32_t{-1};
  };
  // Both columns are sorted by v: one merge-like walk per pair of columns finds the
  // nearest peak for every peak of a column.
  auto link_columns = [&](int from, int to, int side) {
    uint32_t j = start[to];
    const uint32_t end = start[to + 1];
    for (uint32_t i = start[from]; i < start[from + 1]; ++i) {
      int32_t& out = link[2 * i + side];
      out = -1;
      if (j == end) continue;
      while (j + 1 < end && v[j + 1] <= v[i]) ++j;
      uint32_t best = j;
      if (j + 1 < end && std::abs(v[j + 1] - v[i]) < std::abs(v[j] - v[i])) best = j + 1;
      if (within(i, best, 1)) out = static_cast<int32_t>(best);
    }
  };
  for (int c = 0; c < ncols; ++c) {
    for (uint32_t i = start[c]; i < start[c + 1]; ++i) link[2 * i] = link[2 * i + 1] = -1;
    if (c > 0) link_columns(c, c - 1, 0);
    if (c + 1 < ncols) link_columns(c, c + 1, 1);
  }
  // A stripe spans columns: a peak with no neighbour is no stripe (noise on an ambient
  // edge, a speck), and a stripe's end column much dimmer than the column next to it is
  // only partly lit (the stripe turns or is cut inside it, or it holds only the blur past
  // the end): its row is a mixed-pixel guess off the stripe's centre line. A side where
  // the stripe goes on after a one-column gap (a dim stripe dipping under the threshold)
  // is no end.
  dropped->assign(count, 0);
  for (size_t i = 0; i < count; ++i) {
    const int col = p[i].u - x0;
    const int32_t left = link[2 * i], right = link[2 * i + 1];
    if (left >= 0 && right >= 0) continue;
    if ((left < 0 && nearest(col - 2, i, 2) >= 0) || (right < 0 && nearest(col + 2, i, 2) >= 0)) {
      continue;
    }
    if (left < 0 && right < 0) {
      (*dropped)[i] = params.drop_isolated_peaks;
    } else if (p[i].width < kWideStripeFwhmPx) {
      (*dropped)[i] =
          (*dropped)[i] || p[i].intensity < end_ratio * p[left < 0 ? right : left].intensity;
    } else {
      // A wide stripe is blurred as much along u as across it, so its light goes on past its
      // end for a few columns, fading over them: on wide clipped stripes those columns were
      // ~30 false peaks per frame, each less than half as bright as the stripe a few columns
      // in but often more than half its neighbour. So the end is compared with the brightest
      // of the next kWideEndColumns columns in, and while it is dropped the next column in
      // becomes the end (at most kWideEndPeel columns).
      const int side = left < 0 ? 1 : 0;  // links[2j + side] go into the stripe
      int32_t end = static_cast<int32_t>(i);
      for (int peeled = 0; peeled < kWideEndPeel; ++peeled) {
        float brightest = 0;
        int32_t j = link[2 * end + side];
        for (int k = 0; k < kWideEndColumns && j >= 0; ++k, j = link[2 * j + side])
          brightest = std::max(brightest, p[j].intensity);
        if (!(p[end].intensity < end_ratio * brightest)) break;
        (*dropped)[end] = 1;
        end = link[2 * end + side];
        if (link[2 * end + side] < 0 || p[end].width < kWideStripeFwhmPx) break;
      }
    }
  }
  for (size_t i = 0; i < 2 * count; ++i)
    if (link[i] >= 0 && (*dropped)[link[i]]) link[i] = -1;
  if (params.dim_stripe_min_columns > 1 && params.dim_peak_dn > params.threshold_dn) {
    // Noise near the threshold makes peaks, now and then two in a row, but not a stripe:
    // a peak fainter than dim_peak_dn stays only on a stripe of at least
    // dim_stripe_min_columns linked peaks (union-find over the links).
    stripe->resize(2 * count);
    int32_t* root = stripe->data();
    int32_t* size = root + count;
    for (size_t i = 0; i < count; ++i) root[i] = static_cast<int32_t>(i), size[i] = 1;
    auto find = [&](int32_t i) {
      while (root[i] != i) i = root[i] = root[root[i]];
      return i;
    };
    for (size_t i = 0; i < 2 * count; ++i) {
      if (link[i] < 0) continue;
      int32_t a = find(static_cast<int32_t>(i / 2)), b = find(link[i]);
      if (a == b) continue;
      if (size[a] < size[b]) std::swap(a, b);
      root[b] = a;
      size[a] += size[b];
    }
    const float dim = static_cast<float>(params.dim_peak_dn);
    bool any = false;
    for (size_t i = 0; i < count; ++i) {
      if ((*dropped)[i] || !(p[i].intensity < dim)) continue;
      if (size[find(static_cast<int32_t>(i))] < params.dim_stripe_min_columns) {
        (*dropped)[i] = 1;
        any = true;
      }
    }
    if (any) {
      for (size_t i = 0; i < 2 * count; ++i)
        if (link[i] >= 0 && (*dropped)[link[i]]) link[i] = -1;
    }
  }
  if (half_width >= 2) {
    auto bends = [&](int a, int b, int c) { return std::abs(v[a] - 2 * v[b] + v[c]) > kKinkPx; };
    // extent[2i] / extent[2i + 1]: how many columns (up to the half width) the stripe goes on
    // left / right of peak i with each new row continuing its side's local trend (a step
    // or kink ends it): one more than the neighbour's extent, unless the neighbour's
    // neighbour is missing or off the trend. Computed once per peak, not again in every
    // fit that passes through it; left links point to earlier peaks, right links to later
    // ones, so each neighbour's extent is known first.
    extent->resize(2 * count);
    uint8_t* r = extent->data();
    const auto hw = static_cast<uint8_t>(half_width);
    for (size_t i = 0; i < count; ++i) {
      const int32_t l1 = link[2 * i];
      const int32_t l2 = l1 < 0 ? -1 : link[2 * l1];
      r[2 * i] = l1 < 0 ? 0
                 : l2 < 0 || bends(l2, l1, static_cast<int>(i))
                     ? 1
                     : std::min<uint8_t>(hw, r[2 * l1] + 1);
    }
    for (size_t i = count; i-- > 0;) {
      const int32_t r1 = link[2 * i + 1];
      const int32_t r2 = r1 < 0 ? -1 : link[2 * r1 + 1];
      r[2 * i + 1] = r1 < 0 ? 0
                     : r2 < 0 || bends(r2, r1, static_cast<int>(i))
                         ? 1
                         : std::min<uint8_t>(hw, r[2 * r1 + 1] + 1);
    }
    for (size_t i = 0; i < count; ++i) {
      if ((*dropped)[i]) continue;
      int32_t left = link[2 * i], right = link[2 * i + 1];
      // The fit uses pairs u -+ k while both sides extend to k, and not at all if the centre
      // bends (the two columns beside it are off its trend).
      const int m = std::min(r[2 * i], r[2 * i + 1]);
      if (m < 2 || bends(left, static_cast<int>(i), right)) continue;  // 3 samples: the row.
      const float* w = kQuadraticKernels.w[m];
      float row = w[0] * v[i];
      for (int k = 1; k <= m; ++k) {
        row += w[k] * (v[left] + v[right]);
        left = link[2 * left];
        right = link[2 * right + 1];
      }
      p[i].v = row;
    }
  }
  // Compact; rows may have moved past each other by less than the link distance, so keep
  // each column sorted by v.
  size_t write = 0;
  for (int c = 0; c < ncols; ++c) {
    const uint32_t begin = start[c], end = start[c + 1];
    start[c] = static_cast<uint32_t>(write);
    for (uint32_t j = begin; j < end; ++j) {
      if ((*dropped)[j]) continue;
      size_t k = write++;
      const Peak x = p[j];
      for (; k > start[c] && x.v < p[k - 1].v; --k) p[k] = p[k - 1];
      p[k] = x;
    }
  }
  start[ncols] = static_cast<uint32_t>(write);
  peaks->resize(write);
}

struct RowSink {
  PeakExtractor* self;
  const CandidateSearch* search;
  const PeakParams* params;
  std::vector<Candidate>* row;
  std::vector<Peak>* peaks;
};

}  // namespace

void PeakExtractor::RefineRow(void* ctx) {
  const RowSink& sink = *static_cast<const RowSink*>(ctx);
  Peak peak;
  for (const Candidate& c : *sink.row) {
    if (RefineOne(*sink.search, *sink.params, c.u, c.v, &peak)) {
      sink.peaks->push_back(peak);
    }
  }
  sink.row->clear();
}

void PeakExtractor::Extract(const ImageView& image, const PeakParams& params,
                            std::vector<Peak>* out) {
  Run(image, params, /*simd=*/true, out);
}

void PeakExtractor::ExtractScalar(const ImageView& image, const PeakParams& params,
                                  std::vector<Peak>* out) {
  Run(image, params, /*simd=*/false, out);
}

void PeakExtractor::Run(const ImageView& image, const PeakParams& params, bool simd,
                        std::vector<Peak>* out) {
  params.Validate();
  CheckImage(image);
  out->clear();
  peaks_.clear();
  candidates_.clear();
  const Roi roi = ResolveRoi(image, params.roi);
  if (roi.x1 <= roi.x0 || roi.y1 - roi.y0 < 3) return;
  const CandidateSearch search = MakeSearch(image, params, roi);
  RowSink sink{this, &search, &params, &candidates_, &peaks_};
  if (simd) {
    // Rows in order; each row's candidates are refined while its rows are in cache.
    peaks_internal::FindCandidatesSimd(search, &simd_scratch_, &candidates_,
                                       &PeakExtractor::RefineRow, &sink);
  } else {
    // Plain reference: walk each column.
    for (int u = roi.x0; u < roi.x1; ++u) {
      for (int r = roi.y0 + 1; r <= roi.y1 - 2; ++r) {
        if (search.IsCandidate(u, r)) {
          candidates_.push_back({static_cast<uint16_t>(u), static_cast<uint16_t>(r)});
        }
      }
      RefineRow(&sink);
    }
  }

  // Counting sort by column, then per column: sort by v, enforce the separation (keep the
  // stronger), cap the count (keep the strongest).
  const int ncols = roi.x1 - roi.x0;
  column_start_.assign(ncols + 1, 0);
  for (const Peak& p : peaks_) ++column_start_[p.u - roi.x0 + 1];
  for (int i = 0; i < ncols; ++i) column_start_[i + 1] += column_start_[i];
  out->resize(peaks_.size());
  for (const Peak& p : peaks_) (*out)[column_start_[p.u - roi.x0]++] = p;
  // column_start_[i] is now the end of column i.
  size_t write = 0, begin = 0;
  for (int col = 0; col < ncols; ++col) {
    const size_t end = column_start_[col];
    column_start_[col] = static_cast<uint32_t>(write);  // Now where column col's output starts.
    Peak* first = out->data() + begin;
    Peak* last = out->data() + end;
    begin = end;
    if (first == last) continue;
    // Insertion sort: columns hold a few peaks, nearly always in order already.
    for (Peak* it = first + 1; it != last; ++it) {
      const Peak x = *it;
      Peak* j = it;
      for (; j != first && ByRow(x, *(j - 1)); --j) *j = *(j - 1);
      *j = x;
    }
    Peak* kept = first;
    for (Peak* it = first + 1; it != last; ++it) {
      if (it->v - kept->v < params.min_separation_px) {
        if (ByStrength(*it, *kept)) *kept = *it;
      } else {
        *++kept = *it;
      }
    }
    last = kept + 1;
    if (last - first > params.max_peaks_per_column) {
      std::partial_sort(first, first + params.max_peaks_per_column, last, ByStrength);
      last = first + params.max_peaks_per_column;
      std::sort(first, last, ByRow);
    }
    for (Peak* it = first; it != last; ++it) (*out)[write++] = *it;
  }
  column_start_[ncols] = static_cast<uint32_t>(write);
  out->resize(write);
  AlongStripePass(params, ncols, roi.x0, column_start_.data(), &rows_, &links_, &dropped_, &extent_,
                  &stripe_, out);
}

std::vector<Peak> ExtractPeaks(const ImageView& image, const PeakParams& params) {
  PeakExtractor extractor;
  std::vector<Peak> out;
  extractor.Extract(image, params, &out);
  return out;
}

void ExtractPeaks(const ImageView& image, const PeakParams& params, PeakExtractor* extractor,
                  std::vector<Peak>* out) {
  extractor->Extract(image, params, out);
}

std::vector<Peak> ExtractPeaksScalar(const ImageView& image, const PeakParams& params) {
  PeakExtractor extractor;
  std::vector<Peak> out;
  extractor.ExtractScalar(image, params, &out);
  return out;
}

}  // namespace mirrorscan

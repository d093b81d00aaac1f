// SIMD candidate search over rows: every vector holds many columns of one row.
// Compiled once per Highway target (foreach_target.h), chosen at run time.

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "common/peaks/peaks_simd.cc"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <cstring>

#include <hwy/cache_control.h>
#include <hwy/highway.h>

#include "common/peaks/peaks_internal.h"

HWY_BEFORE_NAMESPACE();
namespace mirrorscan {
namespace peaks_internal {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Rounded average (a + b + 1) >> 1 of u8 lanes. Highway 1.0.3's AverageRound on plain SVE
// (not SVE2) adds in 8 bits and overflows; use the overflow-free identity there.
template <class D, class V>
HWY_INLINE V Avg(D d, V a, V b) {
#if HWY_TARGET == HWY_SVE || HWY_TARGET == HWY_SVE_256
  (void)d;
  return hn::Sub(hn::Or(a, b), hn::ShiftRight<1>(hn::Xor(a, b)));
#else
  (void)d;
  return hn::AverageRound(a, b);
#endif
}

// The maximum and step-rule tests of peaks_internal.h for the vector at column x of row r,
// whose contrast test some lane passed (so rarely: out of line, to keep the walk's registers
// free). Appends the candidates.
template <class D, class V>
HWY_NOINLINE void MaximaAt(D d, const CandidateSearch& s, int r, int x, V vc, V al, V ar,
                           std::vector<Candidate>* out) {
  const int w = s.window;
  const auto zero = hn::Zero(d);
  const auto thr = hn::Set(d, static_cast<uint8_t>(s.threshold));
  const auto step_dn = hn::Set(d, static_cast<uint8_t>(CandidateSearch::StepDn(s.threshold)));
  // Rows r - w .. r + w, clamped to the ROI only near its edges.
  const uint8_t* centre = s.data + static_cast<ptrdiff_t>(r) * s.stride + x;
  const bool inside = r - w >= s.y0 && r + w < s.y1;
  auto row = [&](int k) {
    return inside ? centre + static_cast<ptrdiff_t>(k - r) * s.stride
                  : s.data + static_cast<ptrdiff_t>(s.Clamp(k)) * s.stride + x;
  };
  const auto below = hn::SaturatedSub(thr, hn::SaturatedSub(vc, hn::Min(al, ar)));  // 0: passes
  const auto vup = hn::LoadU(d, row(r - 1)), vdn = hn::LoadU(d, row(r + 1));
  const auto rise = hn::SaturatedSub(vc, vup);                        // != 0 iff c > up
  const auto fall = hn::SaturatedSub(vdn, vc);                        // == 0 iff dn <= c
  const auto rise2 = hn::SaturatedSub(vc, hn::LoadU(d, row(r - 2)));  // != 0 iff c > up2
  const auto fall2 = hn::SaturatedSub(hn::LoadU(d, row(r + 2)), vc);  // == 0 iff dn2 <= c
  auto m = hn::AndNot(hn::Or(hn::Eq(rise, zero), hn::Eq(rise2, zero)),
                      hn::Eq(hn::Or(hn::Or(fall, fall2), below), zero));
  if (hn::AllFalse(d, m)) return;
  // The step rule (only where a candidate is). Unsigned compares as saturated differences:
  // a > b iff a - b != 0, a >= b iff b - a == 0.
  const auto flank_diff = hn::Or(hn::SaturatedSub(al, ar), hn::SaturatedSub(ar, al));
  const auto step = hn::Eq(hn::SaturatedSub(step_dn, flank_diff), zero);
  const auto single = hn::Ne(hn::SaturatedSub(vc, vdn), zero);
  const auto maybe = hn::And(m, hn::And(step, single));
  if (!hn::AllFalse(d, maybe)) {
    auto low_up = vup, low_dn = vdn;
    for (int k = 2; k <= w; ++k) {
      low_up = hn::Min(low_up, hn::LoadU(d, row(r - k)));
      low_dn = hn::Min(low_dn, hn::LoadU(d, row(r + k)));
    }
    // 2 low > c + bg, as low - bg > c - low (c >= low, so no wrap-around).
    const auto bg = hn::Min(al, ar);
    const auto no_half_up =
        hn::Ne(hn::SaturatedSub(hn::SaturatedSub(low_up, bg), hn::SaturatedSub(vc, low_up)), zero);
    const auto no_half_dn =
        hn::Ne(hn::SaturatedSub(hn::SaturatedSub(low_dn, bg), hn::SaturatedSub(vc, low_dn)), zero);
    m = hn::AndNot(hn::And(maybe, hn::Or(no_half_up, no_half_dn)), m);
    if (hn::AllFalse(d, m)) return;
  }
  // The mask's bits, 64 lanes to a word (zeroed past the last lane).
  HWY_ALIGN uint8_t bits[(HWY_MAX_BYTES / 8) + 8] = {};
  const size_t nbytes = hn::StoreMaskBits(d, m, bits);
  for (size_t b = 0; b < nbytes; b += 8) {
    uint64_t word;
    std::memcpy(&word, bits + b, sizeof(word));
    while (word != 0) {
      const int bit = __builtin_ctzll(word);
      word &= word - 1;
      out->push_back(
          {static_cast<uint16_t>(x + static_cast<int>(b * 8) + bit), static_cast<uint16_t>(r)});
    }
  }
}

// Walks the rows; every vector holds many columns of one row. Each row's flank mean A(a) (the
// rounded 4-row mean of rows a .. a + 3) is used twice, as the lower flank of row a - w + 3
// and as the upper flank of row a + w, so a ring of rows of those means computes each once:
// row r adds A(r + w - 3) and reads A(r - w), computed 2w - 3 rows before (or before the
// first row). The contrast test comes first: most vectors hold no sample threshold above its
// background, and only those that do read the maximum's rows (MaximaAt).
void FindCandidatesRows(const CandidateSearch& s, std::vector<uint8_t>* scratch,
                        std::vector<Candidate>* out, RowCallback on_row, void* ctx) {
  const hn::ScalableTag<uint8_t> d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int w = s.window;
  const auto zero = hn::Zero(d);
  const auto thr = hn::Set(d, static_cast<uint8_t>(s.threshold));
  const ptrdiff_t stride = s.stride;
  auto row = [&](int r) { return s.data + static_cast<ptrdiff_t>(s.Clamp(r)) * stride; };
  const int n = s.x1 - s.x0;
  const int vec_end = n >= lanes ? s.x0 + (n / lanes) * lanes : s.x0;
  const int vec_n = vec_end - s.x0;
  int ring_rows = 1;  // a power of two >= the 2w - 2 live rows of means
  while (ring_rows < 2 * w - 2) ring_rows *= 2;
  scratch->resize(static_cast<size_t>(ring_rows) * static_cast<size_t>(vec_n));
  // Row a's means, column x at [x - x0].
  auto means = [&](int a) {
    return scratch->data() + static_cast<ptrdiff_t>((a - s.y0 + w) & (ring_rows - 1)) * vec_n;
  };
  auto mean4 = [&](int a, int x) {
    return Avg(d, Avg(d, hn::LoadU(d, row(a) + x), hn::LoadU(d, row(a + 1) + x)),
               Avg(d, hn::LoadU(d, row(a + 2) + x), hn::LoadU(d, row(a + 3) + x)));
  };
  for (int a = s.y0 + 1 - w; a <= s.y0 + w - 3; ++a) {
    uint8_t* m = means(a);
    for (int x = s.x0; x < vec_end; x += lanes) hn::StoreU(mean4(a, x), d, m + (x - s.x0));
  }
  for (int r = s.y0 + 1; r <= s.y1 - 2; ++r) {
    const uint8_t* c = row(r);
    const uint8_t* r0 = row(r + w - 3);
    const uint8_t* r1 = row(r + w - 2);
    const uint8_t* r2 = row(r + w - 1);
    const uint8_t* r3 = row(r + w);
    const uint8_t* upper = means(r - w);
    uint8_t* lower = means(r + w - 3);
    // Row r + w is read here for the first time, and stalled the pass (measured: ~14 us of
    // a 230 us frame); and the refinement of a wide stripe's candidate on row r reads its
    // column out to ~3 sigma + 3 rows below it (peaks.cc, WideCentre), beyond r + w. Fetch
    // row r + 2w while this one is computed (r + w + 2 before: wide frames 288-344 -> 266-269
    // us per frame in alternating runs, cabinet frames within the spread).
    const uint8_t* ahead = row(r + 2 * w);
    for (int x = s.x0; x < vec_end; x += lanes) {
      hwy::Prefetch(ahead + x);
      const auto vc = hn::LoadU(d, c + x);
      const auto ar = Avg(d, Avg(d, hn::LoadU(d, r0 + x), hn::LoadU(d, r1 + x)),
                          Avg(d, hn::LoadU(d, r2 + x), hn::LoadU(d, r3 + x)));
      hn::StoreU(ar, d, lower + (x - s.x0));
      const auto al = hn::LoadU(d, upper + (x - s.x0));
      const auto contrast = hn::SaturatedSub(vc, hn::Min(al, ar));
      if (!hn::AllFalse(d, hn::Eq(hn::SaturatedSub(thr, contrast), zero))) {
        MaximaAt(d, s, r, x, vc, al, ar, out);
      }
    }
    for (int x = vec_end; x < s.x1; ++x) {
      if (s.IsCandidate(x, r)) out->push_back({static_cast<uint16_t>(x), static_cast<uint16_t>(r)});
    }
    if (!out->empty()) on_row(ctx);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace peaks_internal
}  // namespace mirrorscan
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include <hwy/targets.h>

namespace mirrorscan {
namespace peaks_internal {

HWY_EXPORT(FindCandidatesRows);

void FindCandidatesSimd(const CandidateSearch& s, SimdScratch* scratch, std::vector<Candidate>* row,
                        RowCallback on_row, void* ctx) {
  HWY_DYNAMIC_DISPATCH(FindCandidatesRows)(s, &scratch->means, row, on_row, ctx);
}

std::string SimdTargetName() {
  // The target HWY_DYNAMIC_DISPATCH picks: the best one both compiled and supported.
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  return targets.empty() ? "none" : hwy::TargetName(targets.front());
}

}  // namespace peaks_internal
}  // namespace mirrorscan
#endif  // HWY_ONCE

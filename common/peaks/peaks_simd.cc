// SIMD candidate search over rows: every vector holds many columns of one row.
// Compiled once per Highway target (foreach_target.h), chosen at run time.

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "common/peaks/peaks_simd.cc"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

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

void FindCandidatesRows(const CandidateSearch& s, std::vector<Candidate>* out, RowCallback on_row,
                        void* ctx) {
  const hn::ScalableTag<uint8_t> d;
  const size_t lanes = hn::Lanes(d);
  const int w = s.window;
  const auto zero = hn::Zero(d);
  const auto thr = hn::Set(d, static_cast<uint8_t>(s.threshold));
  const auto step_dn = hn::Set(d, static_cast<uint8_t>(CandidateSearch::StepDn(s.threshold)));
  const ptrdiff_t stride = s.stride;
  auto row = [&](int r) { return s.data + static_cast<ptrdiff_t>(s.Clamp(r)) * stride; };
  const int n = s.x1 - s.x0;
  const int vec_end =
      n >= static_cast<int>(lanes) ? s.x0 + static_cast<int>((n / lanes) * lanes) : s.x0;
  HWY_ALIGN uint8_t bits[(HWY_MAX_BYTES / 8) + 8];
  for (int r = s.y0 + 1; r <= s.y1 - 2; ++r) {
    const uint8_t* up = row(r - 1);
    const uint8_t* c = row(r);
    const uint8_t* dn = row(r + 1);
    const uint8_t* up2 = row(r - 2);
    const uint8_t* dn2 = row(r + 2);
    const uint8_t* l0 = row(r - w);
    const uint8_t* l1 = row(r - w + 1);
    const uint8_t* l2 = row(r - w + 2);
    const uint8_t* l3 = row(r - w + 3);
    const uint8_t* r0 = row(r + w - 3);
    const uint8_t* r1 = row(r + w - 2);
    const uint8_t* r2 = row(r + w - 1);
    const uint8_t* r3 = row(r + w);
    // Row r + w is read here for the first time, and stalled the pass (measured: ~14 us of
    // a 230 us frame); fetch the row after next while this one is computed.
    const uint8_t* ahead = row(r + w + 2);
    for (int x = s.x0; x < vec_end; x += static_cast<int>(lanes)) {
      hwy::Prefetch(ahead + x);
      const auto vc = hn::LoadU(d, c + x);
      const auto rise = hn::SaturatedSub(vc, hn::LoadU(d, up + x));  // != 0 iff c > up
      const auto fall = hn::SaturatedSub(hn::LoadU(d, dn + x), vc);  // == 0 iff dn <= c
      const auto al = Avg(d, Avg(d, hn::LoadU(d, l0 + x), hn::LoadU(d, l1 + x)),
                          Avg(d, hn::LoadU(d, l2 + x), hn::LoadU(d, l3 + x)));
      const auto ar = Avg(d, Avg(d, hn::LoadU(d, r0 + x), hn::LoadU(d, r1 + x)),
                          Avg(d, hn::LoadU(d, r2 + x), hn::LoadU(d, r3 + x)));
      const auto contrast = hn::SaturatedSub(vc, hn::Min(al, ar));
      const auto below = hn::SaturatedSub(thr, contrast);              // == 0 iff contrast >= thr
      const auto rise2 = hn::SaturatedSub(vc, hn::LoadU(d, up2 + x));  // != 0 iff c > up2
      const auto fall2 = hn::SaturatedSub(hn::LoadU(d, dn2 + x), vc);  // == 0 iff dn2 <= c
      auto m = hn::AndNot(hn::Or(hn::Eq(rise, zero), hn::Eq(rise2, zero)),
                          hn::Eq(hn::Or(hn::Or(fall, fall2), below), zero));
      if (hn::AllFalse(d, m)) continue;
      // The step rule of peaks_internal.h (only where a candidate is, so rarely). Unsigned
      // compares as saturated differences: a > b iff a - b != 0, a >= b iff b - a == 0.
      const auto flank_diff = hn::Or(hn::SaturatedSub(al, ar), hn::SaturatedSub(ar, al));
      const auto step = hn::Eq(hn::SaturatedSub(step_dn, flank_diff), zero);
      const auto single = hn::Ne(hn::SaturatedSub(vc, hn::LoadU(d, dn + x)), zero);
      const auto maybe = hn::And(m, hn::And(step, single));
      if (!hn::AllFalse(d, maybe)) {
        auto low_up = hn::LoadU(d, up + x), low_dn = hn::LoadU(d, dn + x);
        for (int k = 2; k <= w; ++k) {
          low_up = hn::Min(low_up, hn::LoadU(d, row(r - k) + x));
          low_dn = hn::Min(low_dn, hn::LoadU(d, row(r + k) + x));
        }
        // 2 low > c + bg, as low - bg > c - low (c >= low, so no wrap-around).
        const auto bg = hn::Min(al, ar);
        const auto no_half_up = hn::Ne(
            hn::SaturatedSub(hn::SaturatedSub(low_up, bg), hn::SaturatedSub(vc, low_up)), zero);
        const auto no_half_dn = hn::Ne(
            hn::SaturatedSub(hn::SaturatedSub(low_dn, bg), hn::SaturatedSub(vc, low_dn)), zero);
        m = hn::AndNot(hn::And(maybe, hn::Or(no_half_up, no_half_dn)), m);
        if (hn::AllFalse(d, m)) continue;
      }
      const size_t nbytes = hn::StoreMaskBits(d, m, bits);
      for (size_t b = 0; b < nbytes; ++b) {
        unsigned byte = bits[b];
        while (byte != 0) {
          const int bit = __builtin_ctz(byte);
          byte &= byte - 1;
          out->push_back(
              {static_cast<uint16_t>(x + static_cast<int>(b * 8) + bit), static_cast<uint16_t>(r)});
        }
      }
    }
    for (int x = vec_end; x < s.x1; ++x) {
      if (s.IsCandidate(x, r)) {
        out->push_back({static_cast<uint16_t>(x), static_cast<uint16_t>(r)});
      }
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

void FindCandidatesSimd(const CandidateSearch& s, std::vector<Candidate>* row, RowCallback on_row,
                        void* ctx) {
  HWY_DYNAMIC_DISPATCH(FindCandidatesRows)(s, row, on_row, ctx);
}

std::string SimdTargetName() {
  // The target HWY_DYNAMIC_DISPATCH picks: the best one both compiled and supported.
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  return targets.empty() ? "none" : hwy::TargetName(targets.front());
}

}  // namespace peaks_internal
}  // namespace mirrorscan
#endif  // HWY_ONCE

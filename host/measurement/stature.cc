// The stature: the top of the head, seen or across a hole from the cap below it.
#include "host/measurement/body_analysis.h"

#include <algorithm>

#include "host/measurement/head_cap.h"

namespace mirrorscan::measurement::internal {

void BodyAnalysis::MeasureStature() {
  Measurement m;
  m.name = "stature";
  double head_top = -1e18;
  Eigen::Vector3d top_point = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& v : surface_) {
    if ((v.head<2>() - axis_).norm() <= 150.0 && v.z() > head_top) {
      head_top = v.z();
      top_point = v;
    }
  }
  // A bridge does not make the top seen: any hole near it leaves the highest vertex on
  // its rim, below the true top.
  const Section s = slicer_.AtHeight(head_top - 2.0, /*join_holes=*/false);
  const int head = BodyPart(s);
  if (head < 0 || s.parts[head].has_hole || NearBorder(top_point, top_point, 30.0)) {
    const CapTop cap = ExtrapolateHeadTop(head_top);
    if (cap.withheld) {
      m.withheld = "a hole at the top of the head: " + *cap.withheld;
    } else {
      m.value_mm = cap.z;
      m.confidence = cap.confidence;
      out_.landmarks.push_back({"top_of_head", cap.point});
    }
  } else {
    m.value_mm = head_top;
    m.confidence = 1.0;
    out_.landmarks.push_back({"top_of_head", top_point});
  }
  if (m.withheld) {
    out_.stature_withheld = m.withheld;
  } else {
    out_.stature_mm = m.value_mm;
  }
  Add(m);
}

BodyAnalysis::CapTop BodyAnalysis::ExtrapolateHeadTop(double highest) const {
  CapTop cap;
  // A trimmed mesh's border flares: the points the fit takes keep clear of it.
  std::vector<Eigen::Vector3d> near_border;
  for (const Eigen::Vector3d& b : border_) {
    if (b.z() > highest - kCapSpanMm - kCapBorderClearanceMm &&
        (b.head<2>() - axis_).norm() <= 150.0 + kCapBorderClearanceMm) {
      near_border.push_back(b);
    }
  }
  std::vector<Eigen::Vector3d> points;
  double highest_used = -1e18;
  for (const Eigen::Vector3d& v : surface_) {
    if (v.z() <= highest - kCapSpanMm || (v.head<2>() - axis_).norm() > 150.0) continue;
    const bool clear = std::none_of(near_border.begin(), near_border.end(), [&](const auto& b) {
      return (b - v).squaredNorm() < kCapBorderClearanceMm * kCapBorderClearanceMm;
    });
    if (!clear) continue;
    points.push_back(v);
    highest_used = std::max(highest_used, v.z());
  }
  const std::optional<HeadCapFit> fit = FitHeadCap(points, lateral_);
  if (!fit) {
    cap.withheld = "too little of the head seen below it to fit its cap";
    return cap;
  }
  if (fit->rms_mm > kCapMaxRmsMm) {
    cap.withheld =
        "the head below it is not a smooth cap (the fit's RMS " + Mm(fit->rms_mm, 1) + ")";
    return cap;
  }
  const double rise = fit->top.z() - highest_used;
  if (rise > kCapMaxRiseMm) {
    cap.withheld = "the cap seen below it tops out " + Mm(rise) +
                   " above the highest surface fitted, further than " + Mm(kCapMaxRiseMm);
    return cap;
  }
  const double below = highest - fit->top.z();
  if (below > kCapMaxBelowMm) {
    cap.withheld = "the head's cap fitted below it tops out " + Mm(below) +
                   " below its highest surface, further than " + Mm(kCapMaxBelowMm);
    return cap;
  }
  // A crown flatter than the cap over a small hole: the top is at least the surface seen.
  cap.z = std::max(fit->top.z(), highest);
  cap.point = fit->top;
  cap.point.z() = cap.z;
  cap.confidence = std::clamp(1.0 - std::max(rise, 0.0) / (2.0 * kCapMaxRiseMm), 0.5, 0.95);
  return cap;
}

}  // namespace mirrorscan::measurement::internal

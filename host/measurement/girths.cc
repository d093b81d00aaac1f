// The girths: the torso's (hip, waist, chest, neck) by search, the thighs', and the
// girths at requested heights.
#include "host/measurement/body_analysis.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mirrorscan::measurement::internal {

BodyAnalysis::Extremum BodyAnalysis::Search(double lo, double hi, int sign,
                                            const std::function<double(const TorsoSample&)>& f,
                                            const std::string& what) const {
  Extremum result;
  if (hi - lo < 3 * kStepMm) {
    result.withheld = "no room for the " + what + " between " + Mm(lo) + " and " + Mm(hi);
    return result;
  }
  // Sections a hole crosses are left out; an extremum beside one is not trusted, but
  // for a smallest value: what a hole hides can only add to the hull of what was seen,
  // so a holed section whose seen hull is already clearly larger hides no smaller one
  // (`f` grows with the hull: the tape girth).
  std::vector<double> zs, values;
  std::vector<std::pair<double, double>> holes;  // height, f of the seen part
  for (double z = lo; z <= hi; z += kStepMm) {
    const TorsoSample t = Torso(z);
    if (!t.found) {
      result.withheld = "no torso section at " + Mm(z);
      return result;
    }
    zs.push_back(z);
    if (t.hole) holes.emplace_back(z, f(t));
    values.push_back(t.hole ? -std::numeric_limits<double>::infinity() : sign * f(t));
  }
  const size_t best = std::max_element(values.begin(), values.end()) - values.begin();
  if (!std::isfinite(values[best])) {
    result.withheld = "a hole crosses the torso at every height from " + Mm(lo) + " to " + Mm(hi);
    return result;
  }
  for (const auto& [z, seen] : holes) {
    if (std::abs(z - zs[best]) > 2.5 * kStepMm) continue;
    if (sign < 0 && seen > -values[best] + kHiddenMinimumMarginMm) {
      result.edge_factor = 0.8;  // beside a hole, though not hidden by it
      continue;
    }
    result.withheld = "a hole crosses the torso at " + Mm(z) + ", beside the " + what;
    return result;
  }
  if (best == 0 || best + 1 == values.size()) {
    result.withheld =
        "the " + what + " lies at the edge of its search band (" + Mm(lo) + " to " + Mm(hi) + ")";
    return result;
  }
  if (best < 3 || best + 4 > values.size()) result.edge_factor = 0.8;
  double a = zs[best - 1], b = zs[best + 1];
  auto g = [&](double z) { return sign * f(Torso(z)); };
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  double c = b - ratio * (b - a), d = a + ratio * (b - a);
  double gc = g(c), gd = g(d);
  while (b - a > 0.02) {
    if (gc > gd) {
      b = d;
      d = c;
      gd = gc;
      c = b - ratio * (b - a);
      gc = g(c);
    } else {
      a = c;
      c = d;
      gc = gd;
      d = a + ratio * (b - a);
      gd = g(d);
    }
  }
  result.z = 0.5 * (a + b);
  return result;
}

Measurement BodyAnalysis::TorsoGirth(const std::string& name, const Extremum& e) {
  Measurement m;
  m.name = name;
  if (e.withheld) {
    m.withheld = e.withheld;
    return m;
  }
  const TorsoSample t = Torso(*e.z);
  m.z_mm = *e.z;
  m.value_mm = t.girth;
  m.contour_mm = t.contour;
  m.confidence = GapConfidence(t.gap) * e.edge_factor * t.seen;
  out_.contours.push_back({name, t.hull});
  return m;
}

void BodyAnalysis::MeasureTorso() {
  const std::optional<std::string> blocked = ArmsBlockTorso();
  if (blocked) {
    for (const char* name : {"chest_girth", "waist_girth", "hip_girth"}) {
      Measurement m;
      m.name = name;
      m.withheld = blocked;
      Add(m);
    }
    return;
  }
  const double top = JunctionZ() - kJunctionMarginMm;
  auto girth = [](const TorsoSample& t) { return t.girth; };
  auto depth = [](const TorsoSample& t) { return t.depth; };
  const Extremum hip = Search(crotch_z_ + 1.0, crotch_z_ + 0.5 * (top - crotch_z_), +1, girth,
                              "hip (largest girth above the crotch)");
  Extremum waist;
  if (hip.z) {
    waist = Search(*hip.z, top, -1, girth, "waist (smallest girth above the hip)");
  } else {
    waist.withheld = "it lies above the hip, which is withheld";
  }
  Extremum chest;
  if (waist.z) {
    chest = Search(*waist.z, top, +1, depth, "chest (deepest section above the waist)");
    if (chest.withheld && arms_[0].found && arms_[1].found) {
      *chest.withheld += "; an arm joins the torso at " + Mm(JunctionZ());
    }
  } else {
    chest.withheld = "it lies above the waist, which is withheld";
  }
  Add(TorsoGirth("chest_girth", chest));
  Add(TorsoGirth("waist_girth", waist));
  Add(TorsoGirth("hip_girth", hip));
}

void BodyAnalysis::MeasureThighs() {
  const double z = crotch_z_ - kThighBelowCrotchMm;
  const Section s = slicer_.AtHeight(z);
  const std::array<int, 2> legs = Legs(s);
  for (int side = 0; side < 2; ++side) {
    Measurement m;
    m.name = std::string("thigh_girth_") + SideName(side);
    m.z_mm = z;
    if (crotch_.withheld) {
      m.withheld = "below the crotch, which is withheld";
    } else if (legs[side] < 0) {
      m.withheld = "no leg at " + Mm(z);
    } else if (Holed(s.parts[legs[side]])) {
      m.withheld = "a hole crosses the thigh at " + Mm(z);
    } else {
      const SectionPart& p = s.parts[legs[side]];
      m.value_mm = p.tape_mm;
      m.contour_mm = p.contour_mm;
      m.confidence = GapConfidence(Gap(s, legs[side])) * SeenShare(p);
      out_.contours.push_back({m.name, Hull3(s, p)});
    }
    Add(m);
  }
}

void BodyAnalysis::MeasureNeck() {
  Extremum neck;
  const std::optional<std::string> blocked = ArmsBlockTorso();
  if (blocked) {
    neck.withheld = blocked;
  } else {
    auto girth = [](const TorsoSample& t) { return t.girth; };
    const double from = std::max(arms_[0].junction_z, arms_[1].junction_z);
    const Extremum head = Search(0.85 * top_, 0.98 * top_, +1, girth, "head (widest section)");
    if (!head.z) {
      neck.withheld = head.withheld;
    } else {
      neck = Search(from, *head.z, -1, girth, "neck (narrowest section below the head)");
    }
  }
  Add(TorsoGirth("neck_girth", neck));
}

void BodyAnalysis::GirthAt(double z) {
  const Section s = slicer_.AtHeight(z);
  auto add = [&](const std::string& part, int index) {
    SliceGirth g;
    g.z_mm = z;
    g.part = part;
    if (index < 0) {
      g.withheld = "no " + part + " section at this height";
    } else if (Holed(s.parts[index])) {
      g.withheld = HoleReason(s.parts[index]);
    } else {
      g.girth_mm = s.parts[index].tape_mm;
      g.contour_mm = s.parts[index].contour_mm;
    }
    out_.slices.push_back(g);
  };
  if (s.parts.empty()) {
    out_.slices.push_back({z, "section", std::nullopt, std::nullopt, "no surface at this height"});
  } else if (!out_.human) {
    add("section", 0);
  } else if (z < crotch_z_) {
    const std::array<int, 2> legs = Legs(s);
    add("left_leg", legs[0]);
    add("right_leg", legs[1]);
  } else if (!ArmsBlockTorso() && z < JunctionZ()) {
    add("torso", BodyPart(s));
  } else {
    add("upper_body", BodyPart(s));
  }
}

}  // namespace mirrorscan::measurement::internal

#include "host/measurement/measure.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "host/measurement/head_cap.h"

namespace mirrorscan::measurement {
namespace {

// Definitions docs/measurement.md states (the virtual cabinet's truth follows them).
constexpr double kStepMm = 5.0;               // spacing of the survey sections
constexpr double kThighBelowCrotchMm = 20.0;  // thigh girth: just below the crotch
constexpr double kUpperArmFraction = 0.275;   // of shoulder-to-wrist: mid upper arm
constexpr double kJunctionMarginMm = 10.0;    // torso girths stay this far below the arms' junction
constexpr double kMinPartAreaMm2 = 200.0;     // smaller pieces are specks, not limbs
constexpr double kFullConfidenceGapMm = 20.0;  // a neighbour nearer than this lowers confidence
// A hole across a section is bridged (section.h) where no gap is longer than this and the
// bridges are at most this share of the outline; beyond, the section counts as holed.
constexpr double kMaxBridgeMm = 40.0;
constexpr double kMaxBridgedShare = 0.1;
// A holed section beside a smallest girth whose seen part's hull is longer than it by
// more than this cannot hide a smaller one.
constexpr double kHiddenMinimumMarginMm = 5.0;
// The top of the head across a hole (ExtrapolateHeadTop): the cap is fitted to the mesh's
// vertices over this span below its highest vertex, this far from any border at least,
// and trusted up to this far above the highest of them and this RMS. Within 20 mm the
// model's own error is at most 0.5 mm for a profile |z/c|^2.5 rather than an ellipse's
// ^2, and 1.6 mm for a head nodding 10 degrees with its back open (docs/measurement.md).
constexpr double kCapSpanMm = 50.0;
constexpr double kCapBorderClearanceMm = 10.0;
constexpr double kCapMaxRiseMm = 20.0;
constexpr double kCapMaxRmsMm = 0.5;

std::string Mm(double x, int decimals = 0) {
  std::ostringstream out;
  out.precision(decimals);
  out << std::fixed << x << " mm";
  return out.str();
}

const char* SideName(int side) { return side == 0 ? "left" : "right"; }

struct TorsoSample {
  bool found = false;
  bool hole = false;
  double girth = 0.0, contour = 0.0, depth = 0.0, gap = 0.0, seen = 1.0;
  std::vector<Eigen::Vector3d> hull;
};

struct Arm {
  bool found = false;
  bool raised = false;
  double junction_z = 0.0;
  double radius = 0.0;
  std::vector<Eigen::Vector3d> centroids;  // of its horizontal sections, hand to junction
  double hand_z = 0.0;                     // the run's far end
};

class Analysis {
 public:
  Analysis(const Slicer& slicer, BodyMeasurements& out) : slicer_(slicer), out_(out) {
    // The surface's vertices: those a triangle uses (a vertex of none is not surface).
    std::vector<bool> used(slicer.mesh().vertices.size(), false);
    // The mesh's borders: edges of one triangle only.
    std::map<std::pair<int, int>, int> edges;
    for (const Eigen::Vector3i& t : slicer.mesh().triangles) {
      for (int k = 0; k < 3; ++k) {
        used[t[k]] = true;
        ++edges[std::minmax(t[k], t[(k + 1) % 3])];
      }
    }
    for (size_t i = 0; i < used.size(); ++i) {
      if (!used[i]) continue;
      const Eigen::Vector3d& v = slicer.mesh().vertices[i];
      surface_.push_back(v);
      top_ = std::max(top_, v.z());
      bottom_ = std::min(bottom_, v.z());
    }
    for (const auto& [edge, count] : edges) {
      if (count == 1) border_.push_back(slicer.mesh().vertices[edge.first]);
    }
  }

  void Run(const MeasureOptions& options) {
    if (!FindLegsAndCrotch() || !FindTorsoAxis()) {
      WithholdAll("not a human body: " + not_human_);
    } else {
      out_.human = true;
      out_.lateral = lateral_;
      FindArms();
      MeasureStature();
      Add(crotch_);
      MeasureTorso();
      MeasureThighs();
      MeasureNeck();
      MeasureArms();
    }
    for (double z : options.girth_at_mm) GirthAt(z);
  }

 private:
  // ---- Sections ---------------------------------------------------------------------
  static bool Significant(const SectionPart& p) { return p.area_mm2 >= kMinPartAreaMm2; }

  double Lateral(const Eigen::Vector2d& p) const { return (p - axis_).dot(lateral_); }

  // The part holding `point` (inside its hull), else the significant part nearest it.
  static int PartAt(const Section& s, const Eigen::Vector2d& point, double max_distance) {
    int best = -1;
    double best_distance = max_distance;
    for (int i = 0; i < static_cast<int>(s.parts.size()); ++i) {
      const SectionPart& p = s.parts[i];
      if (!Significant(p)) continue;
      if (p.Contains(point)) return i;
      const double d = (p.centroid - point).norm();
      if (d < best_distance) {
        best_distance = d;
        best = i;
      }
    }
    return best;
  }

  // The body's central part at z: the part holding the torso axis.
  int BodyPart(const Section& s) const { return PartAt(s, axis_, 150.0); }

  // Legs below the crotch: on each side, the significant part nearest the axis.
  std::array<int, 2> Legs(const Section& s) const {
    std::array<int, 2> legs = {-1, -1};
    std::array<double, 2> nearest = {1e18, 1e18};
    for (int i = 0; i < static_cast<int>(s.parts.size()); ++i) {
      if (!Significant(s.parts[i])) continue;
      const double offset = Lateral(s.parts[i].centroid);
      const int side = offset >= 0.0 ? 0 : 1;
      if (std::abs(offset) < nearest[side]) {
        nearest[side] = std::abs(offset);
        legs[side] = i;
      }
    }
    return legs;
  }

  // The arm's part on `side` at z, or -1: the largest significant part that is neither
  // the torso (above the crotch) nor a leg (below).
  int ArmPart(const Section& s, double z, int side) const {
    std::vector<int> taken;
    if (z >= crotch_z_) {
      taken.push_back(BodyPart(s));
    } else {
      const std::array<int, 2> legs = Legs(s);
      taken.assign(legs.begin(), legs.end());
    }
    for (int i = 0; i < static_cast<int>(s.parts.size()); ++i) {
      if (!Significant(s.parts[i]) || std::count(taken.begin(), taken.end(), i)) continue;
      const double offset = Lateral(s.parts[i].centroid);
      if ((offset >= 0.0) == (side == 0)) return i;  // parts are sorted by area
    }
    return -1;
  }

  static std::vector<Eigen::Vector3d> Hull3(const Section& s, const SectionPart& p) {
    std::vector<Eigen::Vector3d> hull;
    for (const Eigen::Vector2d& q : p.hull) hull.push_back(s.ToWorld(q));
    return hull;
  }

  static double Gap(const Section& s, int part) {
    double gap = std::numeric_limits<double>::infinity();
    for (int i = 0; i < static_cast<int>(s.parts.size()); ++i) {
      if (i != part && Significant(s.parts[i])) {
        gap = std::min(gap, s.parts[part].DistanceTo(s.parts[i]));
      }
    }
    return gap;
  }

  static double GapConfidence(double gap) { return std::min(1.0, gap / kFullConfidenceGapMm); }

  // A part the data do not close: a hole across it that no allowed bridge spans.
  static bool Holed(const SectionPart& p) {
    return p.has_hole && !(p.bridged && p.largest_bridge_mm <= kMaxBridgeMm &&
                           p.bridged_mm <= kMaxBridgedShare * p.contour_mm);
  }
  // Why a holed part is not bridged.
  static std::string HoleReason(const SectionPart& p) {
    if (!p.bridged) return "a hole crosses the section (its sides do not join smoothly)";
    if (p.largest_bridge_mm > kMaxBridgeMm) {
      return "a hole " + Mm(p.largest_bridge_mm) + " across crosses the section (at most " +
             Mm(kMaxBridgeMm) + " is bridged)";
    }
    return "holes cross " + Mm(p.bridged_mm) + " of the section's " + Mm(p.contour_mm) +
           " (at most " + std::to_string(static_cast<int>(100 * kMaxBridgedShare)) +
           " % is bridged)";
  }
  // The share of a part's outline that was seen.
  static double SeenShare(const SectionPart& p) {
    return p.bridged && p.contour_mm > 0.0 ? 1.0 - p.bridged_mm / p.contour_mm : 1.0;
  }

  TorsoSample Torso(double z) const {
    const Section s = slicer_.AtHeight(z);
    TorsoSample sample;
    const int body = BodyPart(s);
    if (body < 0) return sample;
    const SectionPart& p = s.parts[body];
    sample.found = true;
    sample.hole = Holed(p);
    sample.seen = SeenShare(p);
    sample.girth = p.tape_mm;
    sample.contour = p.contour_mm;
    const Eigen::Vector2d front(lateral_.y(), -lateral_.x());
    double lo = 1e18, hi = -1e18;
    for (const Eigen::Vector2d& q : p.hull) {
      lo = std::min(lo, q.dot(front));
      hi = std::max(hi, q.dot(front));
    }
    sample.depth = hi - lo;
    sample.gap = Gap(s, body);
    sample.hull = Hull3(s, p);
    return sample;
  }

  // ---- Legs, crotch, axis ---------------------------------------------------------------
  bool FindLegsAndCrotch() {
    if (top_ <= 0.0) {
      not_human_ = "nothing stands above the floor";
      return false;
    }
    const double z_leg = 0.25 * top_;
    const Section s = slicer_.AtHeight(z_leg, /*join_holes=*/false);
    std::vector<const SectionPart*> parts;
    for (const SectionPart& p : s.parts) {
      if (Significant(p)) parts.push_back(&p);
    }
    if (parts.size() < 2) {
      not_human_ = "one part at a quarter of its height (" + Mm(z_leg) + "), not two legs";
      return false;
    }
    if (parts[1]->area_mm2 < 0.4 * parts[0]->area_mm2 ||
        (parts.size() > 2 && parts[2]->area_mm2 > 0.3 * parts[1]->area_mm2)) {
      not_human_ = std::to_string(parts.size()) + " parts at a quarter of its height (" +
                   Mm(z_leg) + "), not a pair of legs";
      return false;
    }
    std::array<Eigen::Vector2d, 2> legs = {parts[0]->centroid, parts[1]->centroid};
    if (Holed(*parts[0]) || Holed(*parts[1])) {
      crotch_.withheld = "a hole crosses the legs at " + Mm(z_leg);
    }
    // Up from there until one part holds both legs: the crotch.
    auto merged = [&](double z, std::array<Eigen::Vector2d, 2>& tracked, bool* hole) {
      const Section section = slicer_.AtHeight(z, /*join_holes=*/false);
      const int a = PartAt(section, tracked[0], 100.0), b = PartAt(section, tracked[1], 100.0);
      if (a < 0 || b < 0) return true;
      if (hole) *hole = Holed(section.parts[a]) || Holed(section.parts[b]);
      if (a == b) return true;
      tracked = {section.parts[a].centroid, section.parts[b].centroid};
      return false;
    };
    double z = z_leg;
    for (; z < 0.7 * top_; z += kStepMm) {
      std::array<Eigen::Vector2d, 2> next = legs;
      bool hole = false;
      if (merged(z + kStepMm, next, &hole)) break;
      legs = next;
    }
    if (z >= 0.7 * top_) {
      not_human_ = "its two lower parts never join below " + Mm(0.7 * top_);
      return false;
    }
    double lo = z, hi = z + kStepMm;
    bool hole = false;
    for (int i = 0; i < 14; ++i) {
      const double mid = 0.5 * (lo + hi);
      std::array<Eigen::Vector2d, 2> next = legs;
      bool h = false;
      if (merged(mid, next, &h)) {
        hi = mid;
      } else {
        lo = mid;
        legs = next;
        hole |= h;
      }
    }
    crotch_z_ = 0.5 * (lo + hi);
    // Where the legs first meet, the scan must have seen them meet. Sections here join no
    // holes: whether two open-sided thighs meet is what a hole hides (the crotch is rarely
    // seen), and a bridge would guess it.
    {
      const Section above = slicer_.AtHeight(hi, /*join_holes=*/false);
      const int joined = PartAt(above, legs[0], 100.0);
      if (joined >= 0 && above.parts[joined].has_hole && !crotch_.withheld) {
        crotch_.withheld = "the legs meet inside a hole at " + Mm(hi) + ": the crotch is not seen";
      }
    }
    if (crotch_z_ < 0.3 * top_ || crotch_z_ > 0.6 * top_) {
      not_human_ = "its lower parts join at " + Mm(crotch_z_) + ", not at a crotch's height";
      return false;
    }
    leg_points_ = legs;
    axis_ = 0.5 * (legs[0] + legs[1]);
    crotch_.name = "crotch_height";
    if (hole) crotch_.withheld = "a hole crosses the legs just below the crotch";
    if (!crotch_.withheld) {
      crotch_.value_mm = crotch_z_;
      crotch_.confidence = 1.0;
      out_.landmarks.push_back({"crotch", Eigen::Vector3d(axis_.x(), axis_.y(), crotch_z_)});
    }
    return true;
  }

  bool FindTorsoAxis() {
    const double z = crotch_z_ + 0.3 * (top_ - crotch_z_);
    const Section s = slicer_.AtHeight(z);
    const int body = PartAt(s, axis_, 150.0);
    if (body < 0) {
      not_human_ = "no torso above the legs at " + Mm(z);
      return false;
    }
    const SectionPart& p = s.parts[body];
    axis_ = p.centroid;
    // The hull's area moments: its vertices crowd where the section bends, so their
    // scatter would tilt the axes.
    std::vector<cv::Point2f> hull;
    for (const Eigen::Vector2d& q : p.hull) hull.emplace_back(q.x(), q.y());
    const cv::Moments moments = cv::moments(hull);
    Eigen::Matrix2d covariance;
    covariance << moments.mu20, moments.mu11, moments.mu11, moments.mu02;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(covariance);
    lateral_ = solver.eigenvectors().col(1);  // the wider axis: left to right
    // The subject faces the camera (-y): its front, lateral turned clockwise, has y < 0.
    const Eigen::Vector2d front(lateral_.y(), -lateral_.x());
    if (front.y() > 0.0) lateral_ = -lateral_;
    // Which leg is the left one, now that left is known.
    if (Lateral(leg_points_[0]) < Lateral(leg_points_[1]))
      std::swap(leg_points_[0], leg_points_[1]);
    return true;
  }

  // ---- Arms -------------------------------------------------------------------------------
  void FindArms() {
    struct Hit {
      double z;
      Eigen::Vector3d centroid;
      double area;
    };
    std::array<std::vector<std::vector<Hit>>, 2> runs;
    std::array<bool, 2> open = {false, false};
    for (double z = std::max(bottom_, 0.0) + kStepMm; z < top_; z += kStepMm) {
      const Section s = slicer_.AtHeight(z);
      for (int side = 0; side < 2; ++side) {
        const int part = ArmPart(s, z, side);
        if (part < 0) {
          open[side] = false;
          continue;
        }
        if (!open[side]) runs[side].emplace_back();
        open[side] = true;
        const SectionPart& p = s.parts[part];
        runs[side].back().push_back(
            {z, Eigen::Vector3d(p.centroid.x(), p.centroid.y(), z), p.area_mm2});
      }
    }
    for (int side = 0; side < 2; ++side) {
      Arm& arm = arms_[side];
      const std::vector<Hit>* longest = nullptr;
      for (const std::vector<Hit>& run : runs[side]) {
        if (!longest || run.size() > longest->size()) longest = &run;
      }
      if (!longest || longest->size() * kStepMm < 150.0) continue;
      arm.found = true;
      const Hit& low = longest->front();
      const Hit& high = longest->back();
      const double low_out = std::abs(Lateral(low.centroid.head<2>()));
      const double high_out = std::abs(Lateral(high.centroid.head<2>()));
      arm.raised = high_out > low_out;
      double area = 0.0;
      for (const Hit& hit : *longest) {
        arm.centroids.push_back(hit.centroid);
        area = std::max(area, hit.area);
      }
      arm.radius = std::sqrt(area / std::numbers::pi);
      arm.hand_z = arm.raised ? high.z : low.z;
      // Refine the junction: the last height at which the arm is still apart.
      double apart = arm.raised ? low.z : high.z;
      double joined = arm.raised ? low.z - kStepMm : high.z + kStepMm;
      for (int i = 0; i < 12; ++i) {
        const double mid = 0.5 * (apart + joined);
        (ArmPart(slicer_.AtHeight(mid), mid, side) >= 0 ? apart : joined) = mid;
      }
      arm.junction_z = apart;
    }
  }

  // Why the torso's girths cannot be taken, if they cannot.
  std::optional<std::string> ArmsBlockTorso() const {
    for (int side = 0; side < 2; ++side) {
      if (!arms_[side].found) {
        return std::string("the ") + SideName(side) +
               " arm is not told apart from the torso (merged with it, or missing)";
      }
    }
    return std::nullopt;
  }

  double JunctionZ() const { return std::min(arms_[0].junction_z, arms_[1].junction_z); }

  // ---- Measurements ------------------------------------------------------------------------
  void Add(Measurement m) {
    if (m.withheld) {
      m.value_mm.reset();
      m.contour_mm.reset();
      m.confidence = 0.0;
    }
    out_.measurements.push_back(std::move(m));
  }

  void WithholdAll(const std::string& reason) {
    out_.stature_withheld = reason;
    for (const char* name :
         {"stature", "crotch_height", "chest_girth", "waist_girth", "hip_girth", "thigh_girth_left",
          "thigh_girth_right", "neck_girth", "upper_arm_girth_left", "upper_arm_girth_right",
          "shoulder_breadth", "arm_length_left", "arm_length_right"}) {
      Measurement m;
      m.name = name;
      m.withheld = reason;
      Add(m);
    }
  }

  void MeasureStature() {
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

  struct CapTop {
    double z = 0.0, confidence = 0.0;
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    std::optional<std::string> withheld;
  };

  // Horizontal laser planes graze the top of the head, so a scan often leaves a hole
  // there, and a cabinet whose mirrors end below the top leaves the back of it open too.
  // The top is that of a cap fitted to the seen surface below the hole (head_cap.h), a
  // short way up only: the model's error grows with it (docs/measurement.md).
  CapTop ExtrapolateHeadTop(double highest) const {
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
    if (fit->top.z() < highest - 1.0) {
      cap.withheld = "the head's cap fitted below it tops out below its highest surface";
      return cap;
    }
    cap.z = fit->top.z();
    cap.point = fit->top;
    cap.confidence = std::clamp(1.0 - std::max(rise, 0.0) / (2.0 * kCapMaxRiseMm), 0.5, 0.95);
    return cap;
  }

  struct Extremum {
    std::optional<double> z;
    std::optional<std::string> withheld;
    double edge_factor = 1.0;
  };

  // The height in [lo, hi] where `f` of the torso section is largest (sign +1) or
  // smallest (-1): a survey every kStepMm, then golden-section refinement.
  Extremum Search(double lo, double hi, int sign,
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

  Measurement TorsoGirth(const std::string& name, const Extremum& e) {
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

  void MeasureTorso() {
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

  void MeasureThighs() {
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

  void MeasureNeck() {
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

  // Whether a border vertex of the mesh lies within `r` of the segment from a to b.
  bool NearBorder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) const {
    const Eigen::Vector3d ab = b - a;
    const double length2 = ab.squaredNorm();
    for (const Eigen::Vector3d& v : border_) {
      const double t = length2 > 0.0 ? std::clamp((v - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
      if ((a + t * ab - v).norm() <= r) return true;
    }
    return false;
  }

  // The first point past `inside` along `direction` where the line leaves the body.
  std::optional<Eigen::Vector3d> ExitAlong(const Eigen::Vector3d& inside,
                                           const Eigen::Vector3d& direction) const {
    const std::vector<LineCrossing> crossings = CrossLine(slicer_.mesh(), inside, direction);
    int depth = 0;  // surfaces around the point, counted from far behind `inside`
    for (const LineCrossing& c : crossings) {
      depth -= c.sign;
      if (c.t > 1e-9 && depth == 0) return inside + c.t * direction;
    }
    return std::nullopt;
  }

  void MeasureArms() {
    std::array<std::optional<Eigen::Vector3d>, 2> shoulders;
    std::array<std::optional<std::string>, 2> why;
    std::array<Measurement, 2> lengths, girths;
    for (int side = 0; side < 2; ++side) {
      Arm& arm = arms_[side];
      lengths[side].name = std::string("arm_length_") + SideName(side);
      girths[side].name = std::string("upper_arm_girth_") + SideName(side);
      if (!arm.found) {
        why[side] = std::string("the ") + SideName(side) + " arm is not told apart from the torso";
      } else if (arm.raised) {
        why[side] = "arms raised above the shoulders: no shoulder point in this pose";
      } else {
        MeasureArm(side, shoulders[side], why[side], lengths[side], girths[side]);
      }
      if (why[side]) lengths[side].withheld = girths[side].withheld = why[side];
    }
    Measurement breadth;
    breadth.name = "shoulder_breadth";
    if (shoulders[0] && shoulders[1]) {
      breadth.value_mm = (*shoulders[0] - *shoulders[1]).norm();
      breadth.confidence = std::min(lengths[0].confidence, lengths[1].confidence);
    } else {
      breadth.withheld = why[0] ? why[0] : why[1];
    }
    Add(girths[0]);
    Add(girths[1]);
    Add(breadth);
    Add(lengths[0]);
    Add(lengths[1]);
  }

  void MeasureArm(int side, std::optional<Eigen::Vector3d>& shoulder,
                  std::optional<std::string>& why, Measurement& length, Measurement& girth) {
    const Arm& arm = arms_[side];
    // Axis: a line through the centres of the arm's sections, clear of both ends.
    std::vector<Eigen::Vector3d> points;
    for (const Eigen::Vector3d& c : arm.centroids) {
      if (c.z() > arm.hand_z + 20.0 && c.z() < arm.junction_z - 20.0) points.push_back(c);
    }
    if (points.size() < 5) {
      why = "too short a stretch of the " + std::string(SideName(side)) +
            " arm is apart from the torso";
      return;
    }
    Eigen::Vector3d mean, down;
    auto fit = [&mean, &down](const std::vector<Eigen::Vector3d>& centres) {
      mean.setZero();
      for (const Eigen::Vector3d& p : centres) mean += p;
      mean /= static_cast<double>(centres.size());
      Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
      for (const Eigen::Vector3d& p : centres) covariance += (p - mean) * (p - mean).transpose();
      down = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(2);
      if (down.z() > 0.0) down = -down;
    };
    fit(points);
    // A horizontal section's centre is off a tapered, tilted arm's axis; sections square
    // to the axis are centred on it. Two rounds of those.
    const double t_top = (arm.junction_z - 20.0 - mean.z()) / down.z();
    const double t_low = (arm.hand_z + 20.0 - mean.z()) / down.z();
    for (int round = 0; round < 2; ++round) {
      std::vector<Eigen::Vector3d> centres;
      for (int k = 0; k <= 10; ++k) {
        const Eigen::Vector3d at = mean + (t_top + (t_low - t_top) * k / 10.0) * down;
        const Section s = slicer_.ByPlane(at, down);
        const int part = PartAt(s, Eigen::Vector2d::Zero(), arm.radius);
        if (part >= 0 && !Holed(s.parts[part]))
          centres.push_back(s.ToWorld(s.parts[part].centroid));
      }
      if (centres.size() < 5) break;
      fit(centres);
    }
    // Wrist: the far end of the arm along its axis (the arm's own vertices only).
    const double t_junction = (arm.junction_z - mean.z()) / down.z();
    const double t_hand = (arm.hand_z - mean.z()) / down.z();
    double t_wrist = -1e18;
    for (const Eigen::Vector3d& v : surface_) {
      const double t = (v - mean).dot(down);
      if (t < t_junction || t > t_hand + 3.0 * arm.radius) continue;
      if ((v - mean - t * down).norm() <= 1.5 * arm.radius) t_wrist = std::max(t_wrist, t);
    }
    const Eigen::Vector3d wrist = mean + t_wrist * down;
    // A line through a hole crosses no surface there: where a border lies round the arm's
    // far end, or along the axis's way out of the shoulder, the landmark is not seen (a
    // scan's arm ends and shoulder tops) and a crossing further on would be taken for it.
    if (NearBorder(wrist, wrist, 1.5 * arm.radius)) {
      why =
          "a hole at the end of the " + std::string(SideName(side)) + " arm: the wrist is not seen";
      return;
    }
    const Eigen::Vector3d junction_point = mean + t_junction * down;
    const std::optional<Eigen::Vector3d> exit = ExitAlong(junction_point, -down);
    // Up to the exit, or (none found) up to the top of the mesh.
    const Eigen::Vector3d way_out =
        exit ? *exit
             : Eigen::Vector3d(junction_point + (top_ - junction_point.z()) / down.z() * down);
    if (NearBorder(junction_point, way_out, 2.0 * arm.radius)) {
      why = "a hole where the " + std::string(SideName(side)) +
            " arm's axis leaves the body: the shoulder point is not seen";
      return;
    }
    if (!exit) {
      why = "the " + std::string(SideName(side)) +
            " arm's axis never leaves the body above the shoulder";
      return;
    }
    shoulder = *exit;
    out_.landmarks.push_back({std::string("shoulder_") + SideName(side), *exit});
    out_.landmarks.push_back({std::string("wrist_") + SideName(side), wrist});
    length.value_mm = (*exit - wrist).norm();
    length.confidence = 1.0;

    const Eigen::Vector3d upper = *exit + kUpperArmFraction * (wrist - *exit);
    const Section s = slicer_.ByPlane(upper, down);
    const int part = PartAt(s, Eigen::Vector2d::Zero(), arm.radius);
    if (part < 0) {
      girth.withheld = "no arm section at the upper-arm point";
    } else if (Holed(s.parts[part])) {
      girth.withheld = "a hole crosses the upper arm";
    } else {
      double reach = 0.0;
      for (const Eigen::Vector2d& q : s.parts[part].hull) reach = std::max(reach, q.norm());
      if (reach > 3.0 * arm.radius) {
        girth.withheld = "the arm is merged with the torso at the upper-arm point";
      } else {
        girth.value_mm = s.parts[part].tape_mm;
        girth.contour_mm = s.parts[part].contour_mm;
        girth.confidence = GapConfidence(Gap(s, part)) * SeenShare(s.parts[part]);
        out_.contours.push_back({girth.name, Hull3(s, s.parts[part])});
      }
    }
  }

  // ---- Girth at a requested height --------------------------------------------------
  void GirthAt(double z) {
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
      out_.slices.push_back(
          {z, "section", std::nullopt, std::nullopt, "no surface at this height"});
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

  const Slicer& slicer_;
  BodyMeasurements& out_;
  std::vector<Eigen::Vector3d> surface_;  // the vertices of the mesh's triangles
  std::vector<Eigen::Vector3d> border_;   // vertices on the mesh's borders (holes)
  double top_ = std::numeric_limits<double>::lowest();
  double bottom_ = std::numeric_limits<double>::max();
  std::string not_human_;
  double crotch_z_ = 0.0;
  Measurement crotch_;
  std::array<Eigen::Vector2d, 2> leg_points_;
  Eigen::Vector2d axis_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d lateral_ = Eigen::Vector2d::UnitX();
  std::array<Arm, 2> arms_;
};

nlohmann::json Nullable(const std::optional<double>& x) {
  return x ? nlohmann::json(*x) : nlohmann::json(nullptr);
}
nlohmann::json Nullable(const std::optional<std::string>& x) {
  return x ? nlohmann::json(*x) : nlohmann::json(nullptr);
}

std::string CsvField(const std::optional<double>& x) {
  if (!x) return "";
  std::ostringstream out;
  out.precision(10);
  out << *x;
  return out.str();
}

std::string CsvText(const std::optional<std::string>& x) {
  if (!x) return "";
  std::string quoted = "\"";
  for (char c : *x) quoted += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace

const Measurement* BodyMeasurements::Find(const std::string& name) const {
  for (const Measurement& m : measurements) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

BodyMeasurements MeasureBody(const TriangleMesh& mesh, const MeasureOptions& options) {
  if (mesh.triangles.empty()) throw std::invalid_argument("the mesh has no triangles");
  const Slicer slicer(WeldVertices(mesh));
  BodyMeasurements out;
  Analysis(slicer, out).Run(options);
  return out;
}

nlohmann::json ToJson(const BodyMeasurements& body) {
  nlohmann::json json;
  json["stature_mm"] = Nullable(body.stature_mm);
  json["human"] = body.human;
  json["measurements"] = nlohmann::json::array();
  for (const Measurement& m : body.measurements) {
    json["measurements"].push_back({{"name", m.name},
                                    {"value_mm", Nullable(m.value_mm)},
                                    {"z_mm", Nullable(m.z_mm)},
                                    {"contour_mm", Nullable(m.contour_mm)},
                                    {"confidence", m.confidence},
                                    {"withheld", Nullable(m.withheld)}});
  }
  json["slices"] = nlohmann::json::array();
  for (const SliceGirth& s : body.slices) {
    json["slices"].push_back({{"z_mm", s.z_mm},
                              {"part", s.part},
                              {"girth_mm", Nullable(s.girth_mm)},
                              {"contour_mm", Nullable(s.contour_mm)},
                              {"withheld", Nullable(s.withheld)}});
  }
  json["landmarks"] = nlohmann::json::array();
  for (const Landmark& l : body.landmarks) {
    json["landmarks"].push_back(
        {{"name", l.name}, {"point_mm", {l.point_mm.x(), l.point_mm.y(), l.point_mm.z()}}});
  }
  return json;
}

std::string ToCsv(const BodyMeasurements& body) {
  std::ostringstream out;
  out << "name,value_mm,z_mm,contour_mm,confidence,withheld\n";
  for (const Measurement& m : body.measurements) {
    out << m.name << ',' << CsvField(m.value_mm) << ',' << CsvField(m.z_mm) << ','
        << CsvField(m.contour_mm) << ',' << m.confidence << ',' << CsvText(m.withheld) << '\n';
  }
  for (const SliceGirth& s : body.slices) {
    out << "girth_at:" << s.part << ',' << CsvField(s.girth_mm) << ',' << CsvField(s.z_mm) << ','
        << CsvField(s.contour_mm) << ',' << (s.withheld ? 0.0 : 1.0) << ',' << CsvText(s.withheld)
        << '\n';
  }
  return out.str();
}

}  // namespace mirrorscan::measurement

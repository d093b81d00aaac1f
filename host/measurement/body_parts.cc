// The body's parts in its sections (legs, crotch, torso axis, arms) and lines through it.
#include "host/measurement/body_analysis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

namespace mirrorscan::measurement::internal {

BodyAnalysis::BodyAnalysis(const Slicer& slicer, BodyMeasurements& out)
    : slicer_(slicer), out_(out) {
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

int BodyAnalysis::PartAt(const Section& s, const Eigen::Vector2d& point, double max_distance) {
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

std::array<int, 2> BodyAnalysis::Legs(const Section& s) const {
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

int BodyAnalysis::ArmPart(const Section& s, double z, int side) const {
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

std::vector<Eigen::Vector3d> BodyAnalysis::Hull3(const Section& s, const SectionPart& p) {
  std::vector<Eigen::Vector3d> hull;
  for (const Eigen::Vector2d& q : p.hull) hull.push_back(s.ToWorld(q));
  return hull;
}

double BodyAnalysis::Gap(const Section& s, int part) {
  double gap = std::numeric_limits<double>::infinity();
  for (int i = 0; i < static_cast<int>(s.parts.size()); ++i) {
    if (i != part && Significant(s.parts[i])) {
      gap = std::min(gap, s.parts[part].DistanceTo(s.parts[i]));
    }
  }
  return gap;
}

bool BodyAnalysis::Holed(const SectionPart& p) {
  return p.has_hole && !(p.bridged && p.largest_bridge_mm <= kMaxBridgeMm &&
                         p.bridged_mm <= kMaxBridgedShare * p.contour_mm);
}

std::string BodyAnalysis::HoleReason(const SectionPart& p) {
  if (!p.bridged) return "a hole crosses the section (its sides do not join smoothly)";
  if (p.largest_bridge_mm > kMaxBridgeMm) {
    return "a hole " + Mm(p.largest_bridge_mm) + " across crosses the section (at most " +
           Mm(kMaxBridgeMm) + " is bridged)";
  }
  return "holes cross " + Mm(p.bridged_mm) + " of the section's " + Mm(p.contour_mm) +
         " (at most " + std::to_string(static_cast<int>(100 * kMaxBridgedShare)) + " % is bridged)";
}

double BodyAnalysis::SeenShare(const SectionPart& p) {
  return p.bridged && p.contour_mm > 0.0 ? 1.0 - p.bridged_mm / p.contour_mm : 1.0;
}

TorsoSample BodyAnalysis::Torso(double z) const {
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

bool BodyAnalysis::FindLegsAndCrotch() {
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
    not_human_ = std::to_string(parts.size()) + " parts at a quarter of its height (" + Mm(z_leg) +
                 "), not a pair of legs";
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

bool BodyAnalysis::FindTorsoAxis() {
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
  if (Lateral(leg_points_[0]) < Lateral(leg_points_[1])) std::swap(leg_points_[0], leg_points_[1]);
  return true;
}

void BodyAnalysis::FindArms() {
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

std::optional<std::string> BodyAnalysis::ArmsBlockTorso() const {
  for (int side = 0; side < 2; ++side) {
    if (!arms_[side].found) {
      return std::string("the ") + SideName(side) +
             " arm is not told apart from the torso (merged with it, or missing)";
    }
  }
  return std::nullopt;
}

bool BodyAnalysis::NearBorder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) const {
  const Eigen::Vector3d ab = b - a;
  const double length2 = ab.squaredNorm();
  for (const Eigen::Vector3d& v : border_) {
    const double t = length2 > 0.0 ? std::clamp((v - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    if ((a + t * ab - v).norm() <= r) return true;
  }
  return false;
}

std::optional<Eigen::Vector3d> BodyAnalysis::ExitAlong(const Eigen::Vector3d& inside,
                                                       const Eigen::Vector3d& direction) const {
  const std::vector<LineCrossing> crossings = CrossLine(slicer_.mesh(), inside, direction);
  int depth = 0;  // surfaces around the point, counted from far behind `inside`
  for (const LineCrossing& c : crossings) {
    depth -= c.sign;
    if (c.t > 1e-9 && depth == 0) return inside + c.t * direction;
  }
  return std::nullopt;
}

}  // namespace mirrorscan::measurement::internal

// The arms' measurements along their axes: shoulder breadth, arm lengths, upper-arm girths.
#include "host/measurement/body_analysis.h"

#include <algorithm>

#include <Eigen/Eigenvalues>

namespace mirrorscan::measurement::internal {

void BodyAnalysis::MeasureArms() {
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

void BodyAnalysis::MeasureArm(int side, std::optional<Eigen::Vector3d>& shoulder,
                              std::optional<std::string>& why, Measurement& length,
                              Measurement& girth) {
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
      if (part >= 0 && !Holed(s.parts[part])) centres.push_back(s.ToWorld(s.parts[part].centroid));
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
    why = "a hole at the end of the " + std::string(SideName(side)) + " arm: the wrist is not seen";
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

}  // namespace mirrorscan::measurement::internal

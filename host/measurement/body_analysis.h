// The analysis behind MeasureBody (measure.h): the body's parts and landmarks found in
// the mesh's sections, then the measurements taken from them. One class, its state the
// landmarks found so far; its members are defined by concern: the parts and landmarks
// (body_parts.cc), the stature (stature.cc), the girths (girths.cc), the arms (arms.cc)
// and the run in order (measure.cc). Internal to host/measurement.
#pragma once

#include <algorithm>
#include <array>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "host/measurement/measure.h"
#include "host/measurement/section.h"

namespace mirrorscan::measurement::internal {

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
// How far the fitted cap may top out below the highest surface seen and the latter stand
// for the top.
constexpr double kCapMaxBelowMm = 5.0;
constexpr double kCapMaxRmsMm = 0.5;

// `x` in mm with `decimals` decimals, for the reasons a value is withheld.
inline std::string Mm(double x, int decimals = 0) {
  std::ostringstream out;
  out.precision(decimals);
  out << std::fixed << x << " mm";
  return out.str();
}

inline const char* SideName(int side) { return side == 0 ? "left" : "right"; }

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

class BodyAnalysis {
 public:
  // Collects the mesh's surface vertices and its border (hole) vertices.
  BodyAnalysis(const Slicer& slicer, BodyMeasurements& out);
  // Finds the body's parts and landmarks and takes every measurement into `out`.
  void Run(const MeasureOptions& options);

 private:
  // ---- Sections (body_parts.cc) --------------------------------------------------------
  static bool Significant(const SectionPart& p) { return p.area_mm2 >= kMinPartAreaMm2; }
  double Lateral(const Eigen::Vector2d& p) const { return (p - axis_).dot(lateral_); }
  // The part holding `point` (inside its hull), else the significant part nearest it.
  static int PartAt(const Section& s, const Eigen::Vector2d& point, double max_distance);
  // The body's central part at z: the part holding the torso axis.
  int BodyPart(const Section& s) const { return PartAt(s, axis_, 150.0); }
  // Legs below the crotch: on each side, the significant part nearest the axis.
  std::array<int, 2> Legs(const Section& s) const;
  // The arm's part on `side` at z, or -1: the largest significant part that is neither
  // the torso (above the crotch) nor a leg (below).
  int ArmPart(const Section& s, double z, int side) const;
  // The part's hull (the tape's path) in the world.
  static std::vector<Eigen::Vector3d> Hull3(const Section& s, const SectionPart& p);
  // How far the nearest other significant part is from `part`.
  static double Gap(const Section& s, int part);
  // A neighbour nearer than kFullConfidenceGapMm lowers a girth's confidence.
  static double GapConfidence(double gap) { return std::min(1.0, gap / kFullConfidenceGapMm); }
  // A part the data do not close: a hole across it that no allowed bridge spans.
  static bool Holed(const SectionPart& p);
  // Why a holed part is not bridged.
  static std::string HoleReason(const SectionPart& p);
  // The share of a part's outline that was seen.
  static double SeenShare(const SectionPart& p);
  // The torso's section at z.
  TorsoSample Torso(double z) const;

  // ---- Legs, crotch, axis, arms (body_parts.cc) ------------------------------------------
  bool FindLegsAndCrotch();
  bool FindTorsoAxis();
  void FindArms();
  // Why the torso's girths cannot be taken, if they cannot.
  std::optional<std::string> ArmsBlockTorso() const;
  double JunctionZ() const { return std::min(arms_[0].junction_z, arms_[1].junction_z); }

  // ---- Measurements (measure.cc) ---------------------------------------------------------
  void Add(Measurement m);
  void WithholdAll(const std::string& reason);

  // ---- Stature (stature.cc) --------------------------------------------------------------
  void MeasureStature();
  struct CapTop {
    double z = 0.0, confidence = 0.0;
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    std::optional<std::string> withheld;
  };
  // Horizontal laser planes graze the top of the head, so a scan often leaves a hole
  // there, and a cabinet whose mirrors end below the top leaves the back of it open too.
  // The top is that of a cap fitted to the seen surface below the hole (head_cap.h), a
  // short way up only: the model's error grows with it (docs/measurement.md).
  CapTop ExtrapolateHeadTop(double highest) const;

  // ---- Girths (girths.cc) ----------------------------------------------------------------
  struct Extremum {
    std::optional<double> z;
    std::optional<std::string> withheld;
    double edge_factor = 1.0;
  };
  // The height in [lo, hi] where `f` of the torso section is largest (sign +1) or
  // smallest (-1): a survey every kStepMm, then golden-section refinement.
  Extremum Search(double lo, double hi, int sign,
                  const std::function<double(const TorsoSample&)>& f,
                  const std::string& what) const;
  Measurement TorsoGirth(const std::string& name, const Extremum& e);
  void MeasureTorso();
  void MeasureThighs();
  void MeasureNeck();

  // ---- Lines through the body (body_parts.cc) --------------------------------------------
  // Whether a border vertex of the mesh lies within `r` of the segment from a to b.
  bool NearBorder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) const;
  // The first point past `inside` along `direction` where the line leaves the body.
  std::optional<Eigen::Vector3d> ExitAlong(const Eigen::Vector3d& inside,
                                           const Eigen::Vector3d& direction) const;

  // ---- Arms: shoulder breadth, arm lengths, upper-arm girths (arms.cc) -------------------
  void MeasureArms();
  void MeasureArm(int side, std::optional<Eigen::Vector3d>& shoulder,
                  std::optional<std::string>& why, Measurement& length, Measurement& girth);

  // ---- Girth at a requested height (girths.cc) -------------------------------------------
  void GirthAt(double z);

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

}  // namespace mirrorscan::measurement::internal

#pragma once
// Test support only (links the virtual cabinet): stretches of the virtual cabinet's sweeps
// as the board stores them, with the renderer's truth for every peak, and scores of a
// cloud or of one rule's decisions against that truth (the sim's truth CSV, in process).
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "common/config/calibration.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/triangulation.h"

namespace mirrorscan::reconstruction::testing_sweeps {

using virtual_cabinet::TruthPeak;

// A stretch of a scene's sweep as the board stores it (peaks per frame), the
// renderer's truth for every frame, and the scene's true calibration.
struct Sweep {
  virtual_cabinet::Scene scene;
  Calibration calibration;
  ScanArchive archive;
  std::map<std::tuple<int, int, int>, std::vector<TruthPeak>> truth;  // (camera, frame, u)
  // The stripes on everything else (floor, panels), the same way.
  std::map<std::tuple<int, int, int>, std::vector<TruthPeak>> background;
  size_t truth_points = 0;
  // Truth points of the subject that the extractor found (a peak within 1 px of the row)
  // and whose ray meets the laser plane at 10° or more: what reconstruction can give.
  size_t truth_reconstructable = 0;
};

// Frames [first_frame, last_frame) of the scene (boards/virtual/scenes/<scene_name>.json)
// with `changes` merged in: the upper and lower camera unless `changes` lists the cameras.
Sweep RenderSweep(const nlohmann::json& changes, int first_frame, int last_frame,
                  const std::string& scene_name = "cuboid");

// Rendered once per test binary.
// The cuboid with 3 lasers, frames 150–239: every laser crosses it (z 1142–1458) in some.
const Sweep& CuboidSweep();
// The mannequin with 3 lasers, frames 150–200: the arms in front of the mirrors and the
// torso in them, laser 1 at z 1000–1250.
const Sweep& MannequinSweep();

// A person in cabinet G (docs/cabinet-design.md: three emitters per laser level, mirrors
// 1000 mm wide from the floor to 2100 mm with their corner 900 mm behind the subject, the
// upper camera at 2400 mm, f 1250 px, lasers of twice the power lighting their whole sheet), set
// here in full rather than left to the scene defaults: the population's f12 (1.90 m, heavy, arms at
// 35°), frames 120–220, where the lower camera sees the arms' silhouettes run along the mirrors'
// stripes, the upper camera the hands at z 800–1000 in the mirrors (outside the core) and the
// chest directly in the mirrors' regions.
const Sweep& PersonInCabinetG();
// Its hands reach 664 mm from the axis: the cylinder for this cabinet (mirrors 779 mm out).
ReconstructOptions CabinetGOptions();

// The truth peak of the subject a peak stands for: same camera, frame and column, the
// nearest row within 2 px; null if none.
const TruthPeak* Match(const Sweep& sweep, int camera, int frame, int u, double v);
const TruthPeak* Match(const Sweep& sweep, const CloudPoint& p);

// Distance from the analytic cuboid's surface (its metadata, not the renderer's mesh), and
// the outward normal of the nearest face; nullopt for points away from the box (tripod).
struct BoxDistance {
  double distance = 0;
  Eigen::Vector3d normal;
  bool near_edge = false;
};
std::optional<BoxDistance> DistanceToCuboid(const virtual_cabinet::Scene& scene,
                                            const Eigen::Vector3d& point);

struct Score {
  size_t points = 0, matched = 0, wrong = 0, found_right = 0;
  double rms_mm = 0, max_mm = 0;
  size_t box_points = 0;
  size_t normals_off = 0;  // more than 10° from the face's normal
};

Score ScoreAgainstTruth(const Sweep& sweep, const PointCloud& cloud);

// The sweep's peaks up to the correspondence rules (Triangulate), for the rules' tests: they
// run the rules before theirs on `t` in Reconstruct()'s order, then their own.
struct RuleBench {
  explicit RuleBench(const Sweep& bench_sweep, const ReconstructOptions& bench_options = {});
  const Sweep& sweep;
  ReconstructOptions options;
  int threads;
  ReconstructSummary summary;
  StageTimer timer;
  Triangulation t;
};

// One rule's decisions (PeakState::rule) against the truth: the peaks it decided, those a
// truth peak of the subject matches, and of those the ones whose chosen hypothesis has
// another laser or view than the truth's.
struct RuleScore {
  size_t decided = 0, matched = 0, wrong = 0;
  size_t wrong_in_centre = 0;  // of the wrong ones, those in the centre view region
};
RuleScore ScoreRule(const Sweep& sweep, const RuleBench& bench, Rule rule);

// Runs the rules in Reconstruct()'s order (reconstruct.cc) up to and including `last`:
// kStereo (one hypothesis, then stereo), kCylinder (then the core), kVolume, kColumnCount,
// kLabelVote.
void DecideUpTo(Rule last, RuleBench* bench);

// The rules up to `rule` on CuboidSweep() and on MannequinSweep() (in that order), and the
// rule's score on each, printed.
std::pair<RuleScore, RuleScore> ScoreOnBothSweeps(Rule rule);

}  // namespace mirrorscan::reconstruction::testing_sweeps

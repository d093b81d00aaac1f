#include "host/reconstruction/test_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "boards/virtual/sweep_peaks.h"
#include "common/config/json_reader.h"
#include "common/parallel/parallel_for.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/rules/column_count.h"
#include "host/reconstruction/rules/cylinder.h"
#include "host/reconstruction/rules/label_vote.h"
#include "host/reconstruction/rules/stereo.h"
#include "host/reconstruction/rules/volume.h"

namespace mirrorscan::reconstruction::testing_sweeps {

using virtual_cabinet::Renderer;
using virtual_cabinet::Scene;

Sweep RenderSweep(const nlohmann::json& changes, int first_frame, int last_frame,
                  const std::string& scene_name) {
  const std::string dir = std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes";
  nlohmann::json scene_json = JsonReader::ParseFile(dir + "/" + scene_name + ".json");
  scene_json.merge_patch(changes);
  Scene scene = Scene::Parse(scene_json, scene_name + ".json", dir);
  // The rules' figures were set against the truth of the upper and lower cameras (what the
  // rpi boards have): the default scene's first two. A sweep takes the third only where it
  // lists its cameras. The three-camera cabinet's figures are the population's
  // (docs/cabinet-design.md).
  if (!changes.contains("cameras")) scene.cameras.resize(2);
  Sweep sweep{std::move(scene), {}, {}, {}, {}, 0, 0};
  sweep.calibration = Calibration::Parse(sweep.scene.TrueCalibration(), "calibration.json");
  const Renderer renderer(sweep.scene);
  sweep.archive.header = virtual_cabinet::SweepArchiveHeader(sweep.scene);
  virtual_cabinet::SweepPeaksOptions options;
  options.first_frame = first_frame;
  options.end_frame = last_frame;
  const auto truth = [&](const FrameRecord& record, double t) {
    const int camera = record.camera;
    const int frame = static_cast<int>(record.sequence);
    const Camera& cam = sweep.scene.cameras[camera].camera;
    for (const TruthPeak& p : renderer.Truth(camera, t)) {
      if (p.material != virtual_cabinet::Material::kSubject) {
        sweep.background[{camera, frame, p.u}].push_back(p);
        continue;
      }
      sweep.truth[{camera, frame, p.u}].push_back(p);
      ++sweep.truth_points;
      const bool detected =
          std::any_of(record.peaks.begin(), record.peaks.end(),
                      [&](const Peak& k) { return k.u == p.u && std::abs(k.v - p.v) < 1.0; });
      // The last ray segment's direction: from the camera, or its mirror image, to the point.
      Eigen::Vector3d eye = cam.CenterInWorld();
      for (int m : virtual_cabinet::MirrorPath(p.view))
        eye = sweep.scene.mirrors[m].plane.ReflectPoint(eye);
      const double sin_angle = std::abs((p.point_in_world - eye).normalized().z());
      if (detected && sin_angle > std::sin(10 * M_PI / 180)) ++sweep.truth_reconstructable;
    }
  };
  sweep.archive.frames = RenderSweepPeaks(sweep.scene, renderer, options, truth);
  sweep.archive.report.complete = true;
  sweep.archive.report.message = "complete";
  return sweep;
}

const Sweep& CuboidSweep() {
  static const Sweep sweep = RenderSweep(nlohmann::json::object(), 150, 240);
  return sweep;
}

const Sweep& MannequinSweep() {
  static const Sweep sweep = RenderSweep({{"lasers", {{"count", 3}}}}, 150, 200, "mannequin");
  return sweep;
}

const Sweep& PersonInCabinetG() {
  static const Sweep sweep = RenderSweep(nlohmann::json::parse(R"({
        "lasers": {"count": 3, "spacing_mm": 200, "start_mm": -50, "speed_mm_s": 150,
                   "emitters_mm": [[0, -900], [-600, -600], [600, -600]], "power": 2,
                   "fan_deg": 360},
        "mirrors": {"width_mm": 1000, "bottom_mm": 0, "height_mm": 2100, "corner_y_mm": 900},
        "frames": 350,
        "cameras": [
          {"name": "upper", "position_mm": [0, -1800, 2400], "look_at_mm": [0, 300, 1550],
           "f_px": 1250},
          {"name": "lower", "position_mm": [0, -1800, 1350], "look_at_mm": [0, 300, 450],
           "f_px": 1250}]})"),
                                         120, 220, "population/f12");
  return sweep;
}

ReconstructOptions CabinetGOptions() {
  ReconstructOptions options;
  options.cylinder.radius_mm = 700;
  return options;
}

const TruthPeak* Match(const Sweep& sweep, int camera, int frame, int u, double v) {
  const auto it = sweep.truth.find({camera, frame, u});
  if (it == sweep.truth.end()) return nullptr;
  const TruthPeak* best = nullptr;
  double best_dv = 2.0;
  for (const TruthPeak& t : it->second) {
    if (std::abs(t.v - v) < best_dv) {
      best_dv = std::abs(t.v - v);
      best = &t;
    }
  }
  return best;
}

const TruthPeak* Match(const Sweep& sweep, const CloudPoint& p) {
  return Match(sweep, p.camera, static_cast<int>(p.frame), static_cast<int>(p.u), p.v);
}

std::optional<BoxDistance> DistanceToCuboid(const virtual_cabinet::Scene& scene,
                                            const Eigen::Vector3d& point) {
  const nlohmann::json& meta = scene.subject.metadata;
  if (!meta.contains("size_mm")) return std::nullopt;  // not the cuboid
  const Eigen::Vector3d size(meta["size_mm"][0], meta["size_mm"][1], meta["size_mm"][2]);
  const Eigen::Vector3d centre(meta["center_mm"][0], meta["center_mm"][1], meta["center_mm"][2]);
  const double yaw = meta["yaw_deg"].get<double>() * M_PI / 180.0;
  const Eigen::Matrix3d world_from_local =
      Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d local = world_from_local.transpose() * (point - centre);
  const Eigen::Vector3d half = size / 2;
  if (std::abs(local.z()) > half.z() + 5) return std::nullopt;
  BoxDistance best{1e9, {}, false};
  for (int axis = 0; axis < 2; ++axis) {
    for (int sign : {-1, 1}) {
      const double d = std::abs(local[axis] - sign * half[axis]);
      if (d < best.distance) {
        best.distance = d;
        best.normal = world_from_local.col(axis) * sign;
        const int other = 1 - axis;
        best.near_edge =
            std::abs(local[other]) > half[other] - 5 || std::abs(local.z()) > half.z() - 5;
      }
    }
  }
  if (best.distance > 20) return std::nullopt;
  return best;
}

Score ScoreAgainstTruth(const Sweep& sweep, const PointCloud& cloud) {
  Score s;
  s.points = cloud.points.size();
  std::map<const TruthPeak*, bool> found;
  for (const CloudPoint& p : cloud.points) {
    const TruthPeak* t = Match(sweep, p);
    if (!t) continue;
    ++s.matched;
    if (t->laser != p.laser || static_cast<int>(t->view) != static_cast<int>(p.view)) {
      ++s.wrong;
      continue;
    }
    found[t] = true;
    const auto box = DistanceToCuboid(sweep.scene, p.point_in_world.cast<double>());
    if (!box || box->near_edge) continue;
    ++s.box_points;
    s.rms_mm += box->distance * box->distance;
    s.max_mm = std::max(s.max_mm, box->distance);
    if (p.normal.cast<double>().dot(box->normal) < std::cos(10 * M_PI / 180)) ++s.normals_off;
  }
  s.found_right = found.size();
  if (s.box_points) s.rms_mm = std::sqrt(s.rms_mm / s.box_points);
  return s;
}

RuleBench::RuleBench(const Sweep& bench_sweep, const ReconstructOptions& bench_options)
    : sweep(bench_sweep),
      options(bench_options),
      threads(ResolveThreads(options.threads)),
      timer(&summary, nullptr),
      t(Triangulate(sweep.archive, sweep.calibration, options, threads, &timer, &summary)) {}

RuleScore ScoreRule(const Sweep& sweep, const RuleBench& bench, Rule rule) {
  RuleScore score;
  for (const PeakState& p : bench.t.table.peaks) {
    if (p.rule != rule || p.chosen < 0) continue;
    ++score.decided;
    const FrameRecord& frame = sweep.archive.frames[p.frame];
    const TruthPeak* truth = Match(sweep, frame.camera, static_cast<int>(frame.sequence), p.u, p.v);
    if (!truth) continue;
    ++score.matched;
    const int key = bench.t.hyp[p.first_hypothesis + p.chosen].key;
    if (key != Key(static_cast<PointView>(truth->view), truth->laser)) {
      ++score.wrong;
      if (p.region == 0) ++score.wrong_in_centre;
    }
  }
  return score;
}

void DecideUpTo(Rule last, RuleBench* bench) {
  Triangulation& t = bench->t;
  const ReconstructOptions& options = bench->options;
  const int threads = bench->threads;
  std::vector<PeakState>& peaks = t.table.peaks;
  DecideByOneHypothesis(threads, &peaks);
  for (const Rule rule :
       {Rule::kStereo, Rule::kCylinder, Rule::kVolume, Rule::kColumnCount, Rule::kLabelVote}) {
    if (rule == Rule::kStereo && options.stereo) {
      ConfirmByStereo(bench->sweep.archive, t.table, t.planes.per_frame, options.stereo_max_mm,
                      threads, &t.hyp);
      DecideByStereo(t.hyp, threads, &peaks);
    }
    if (rule == Rule::kCylinder) DecideByCore(t.hyp, options.cylinder, threads, &peaks);
    if (rule == Rule::kVolume) DecideByVolume(&peaks, t.hyp, options.cylinder, t.geometry, threads);
    if (rule == Rule::kColumnCount) DecideByColumnCount(&t.table, t.hyp, t.planes.count, threads);
    if (rule == Rule::kLabelVote)
      DecideByLabelVote(t.hyp, options, threads, &t.table, &bench->summary);
    if (rule == last) return;
  }
}

std::pair<RuleScore, RuleScore> ScoreOnBothSweeps(Rule rule) {
  std::pair<RuleScore, RuleScore> scores;
  for (const auto& [name, sweep, score] :
       {std::tuple{"cuboid", &CuboidSweep(), &scores.first},
        std::tuple{"mannequin", &MannequinSweep(), &scores.second}}) {
    RuleBench bench(*sweep);
    DecideUpTo(rule, &bench);
    *score = ScoreRule(*sweep, bench, rule);
    std::printf(
        "%s: decided %zu, %zu of them matched to the truth, %zu wrong (%zu in the centre "
        "region)\n",
        name, score->decided, score->matched, score->wrong, score->wrong_in_centre);
  }
  return scores;
}

}  // namespace mirrorscan::reconstruction::testing_sweeps

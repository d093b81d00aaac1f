#include "tests/support/calibration_truth.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "boards/virtual/chessboard.h"
#include "host/calibration/intrinsics.h"

namespace mirrorscan::test_support {

using virtual_cabinet::Renderer;
using virtual_cabinet::View;

std::vector<TruthSample> SweepTruth(const virtual_cabinet::Scene& scene, int frame_step) {
  const Renderer renderer(scene);
  std::vector<TruthSample> samples;
  for (int frame = 0; frame < scene.frames; frame += std::max(1, frame_step)) {
    for (size_t camera = 0; camera < scene.cameras.size(); ++camera) {
      for (const auto& p : renderer.Truth(static_cast<int>(camera), scene.FrameTime(frame))) {
        samples.push_back({static_cast<int>(camera), frame, p.laser, p.view,
                           Eigen::Vector2d(p.u, p.v), p.point_in_world});
      }
    }
  }
  return samples;
}

namespace {

struct Errors {
  std::vector<double> px, mm, outer_px;
};

double Rms(const std::vector<double>& v) {
  double sum2 = 0.0;
  for (double x : v) sum2 += x * x;
  return v.empty() ? 0.0 : std::sqrt(sum2 / v.size());
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * v.size()));
  std::nth_element(v.begin(), v.begin() + i, v.end());
  return v[i];
}

}  // namespace

std::vector<ViewAgreement> CompareWithTruth(const Calibration& estimate,
                                            const virtual_cabinet::Scene& scene,
                                            const std::vector<TruthSample>& truth) {
  std::map<std::pair<int, int>, Errors> errors;
  constexpr double kUnprojectable = 1e3;  // counts as far off
  for (const TruthSample& s : truth) {
    if (s.view != View::kCenter && s.view != View::kLeft && s.view != View::kRight) continue;
    const std::string& name = scene.cameras.at(s.camera).name;
    const CalibrationCamera* camera = estimate.FindCamera(name);
    if (!camera) continue;  // a calibration of one camera of two
    const Plane* mirror = nullptr;
    if (s.view != View::kCenter) {
      const CalibrationMirror* m = estimate.FindMirror(s.view == View::kLeft ? "left" : "right");
      if (!m) throw std::invalid_argument("the calibration has no mirror for this view");
      mirror = &m->plane;
    }
    Errors& e = errors[{s.camera, static_cast<int>(s.view)}];
    const auto projected = mirror ? camera->camera.ProjectViaMirror(s.point_in_world, *mirror)
                                  : camera->camera.ProjectWorld(s.point_in_world);
    const double px = projected ? (*projected - s.pixel).norm() : kUnprojectable;
    e.px.push_back(px);
    const CameraIntrinsics& k = camera->camera.intrinsics;
    if ((s.pixel - Eigen::Vector2d((k.width - 1) / 2.0, (k.height - 1) / 2.0)).norm() > 400.0) {
      e.outer_px.push_back(px);
    }
    double mm = kUnprojectable;
    if (auto ray = camera->camera.RayThroughPixel(s.pixel)) {
      bool ok = true;
      if (mirror) {
        const auto t = IntersectRayPlane(*ray, *mirror);
        ok = t.has_value();
        if (ok) ray = Ray3d{ray->At(*t), mirror->ReflectDirection(ray->direction)};
      }
      const Plane laser_plane = Plane::FromPointNormal(s.point_in_world, scene.lasers.normal);
      if (ok) {
        if (const auto t = IntersectRayPlane(*ray, laser_plane)) {
          mm = (ray->At(*t) - s.point_in_world).norm();
        }
      }
    }
    e.mm.push_back(mm);
  }
  std::vector<ViewAgreement> rows;
  for (const auto& [key, e] : errors) {
    ViewAgreement row;
    row.camera = scene.cameras[key.first].name;
    row.view = virtual_cabinet::ViewName(static_cast<View>(key.second));
    row.points = e.px.size();
    row.rms_px = Rms(e.px);
    row.p99_px = Quantile(e.px, 0.99);
    row.max_px = *std::max_element(e.px.begin(), e.px.end());
    row.rms_mm = Rms(e.mm);
    row.p99_mm = Quantile(e.mm, 0.99);
    row.max_mm = *std::max_element(e.mm.begin(), e.mm.end());
    row.outer_points = e.outer_px.size();
    row.outer_rms_px = Rms(e.outer_px);
    rows.push_back(row);
  }
  return rows;
}

std::string FormatAgreement(const std::vector<ViewAgreement>& rows) {
  std::string text =
      "| camera | view | points | RMS px | p99 px | max px | RMS mm | p99 mm | max mm | "
      "RMS px beyond 400 px |\n|---|---|---|---|---|---|---|---|---|---|\n";
  char line[256];
  for (const ViewAgreement& r : rows) {
    std::snprintf(line, sizeof line,
                  "| %s | %s | %zu | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f (%zu) |\n",
                  r.camera.c_str(), r.view.c_str(), r.points, r.rms_px, r.p99_px, r.max_px,
                  r.rms_mm, r.p99_mm, r.max_mm, r.outer_rms_px, r.outer_points);
    text += line;
  }
  return text;
}

}  // namespace mirrorscan::test_support

namespace mirrorscan::test_support {

namespace fs = std::filesystem;

CabinetLens LensOf(const virtual_cabinet::Scene& scene, int camera) {
  const std::string name = scene.cameras.at(camera).name;
  const fs::path dir = fs::path(MIRRORSCAN_TEST_DATA_DIR) / "chessboard";
  CabinetLens lens;
  lens.captures_dir = dir / name;
  lens.intrinsics_json = dir / (name + "-intrinsics.json");
  const virtual_cabinet::Scene board_scene = virtual_cabinet::Scene::Load(
      fs::path(MIRRORSCAN_SOURCE_DIR) / "boards/virtual/scenes/chessboard.json");
  // A lens of the same camera (intrinsics and pose) is reused.
  nlohmann::json key = {
      {"fx", scene.cameras[camera].camera.intrinsics.fx},
      {"k1", scene.cameras[camera].camera.intrinsics.k1},
      {"k2", scene.cameras[camera].camera.intrinsics.k2},
      {"t",
       {scene.cameras[camera].camera.cam_from_world.translation.x(),
        scene.cameras[camera].camera.cam_from_world.translation.y(),
        scene.cameras[camera].camera.cam_from_world.translation.z()}},
      {"board",
       {board_scene.chessboard->config().inner_columns, board_scene.chessboard->config().inner_rows,
        board_scene.chessboard->config().square_mm, board_scene.seed,
        board_scene.sensor.ambient_dn}}};
  nlohmann::json& poses_key = key["poses"];
  for (const auto& pose : virtual_cabinet::LensCalibrationPoses(
           scene.cameras[camera].camera, board_scene.chessboard->config(), 900.0)) {
    poses_key.push_back({pose.center_mm.x(), pose.center_mm.y(), pose.center_mm.z()});
  }
  const fs::path key_file = dir / (name + "-key.json");
  bool fresh = fs::exists(lens.intrinsics_json) && fs::exists(key_file);
  if (fresh) {
    std::ifstream in(key_file);
    fresh = nlohmann::json::parse(in, nullptr, false) == key;
  }
  if (!fresh) {
    virtual_cabinet::Scene base = board_scene;
    base.cameras = {scene.cameras[camera]};
    base.lasers.power = 0.0;
    const auto poses = virtual_cabinet::LensCalibrationPoses(
        base.cameras[0].camera, board_scene.chessboard->config(), 900.0);
    fs::create_directories(lens.captures_dir);
    std::vector<fs::path> images;
    for (size_t i = 0; i < poses.size(); ++i) {
      virtual_cabinet::Scene s = base;
      s.chessboard.emplace(poses[i]);
      const virtual_cabinet::Renderer renderer(s);
      const auto frame = renderer.RenderFrame(0, 0.0, i, /*lasers_on=*/false);
      const cv::Mat gray(frame.height, frame.width, CV_8UC1,
                         const_cast<uint8_t*>(frame.pixels.data()));
      char file[64];
      std::snprintf(file, sizeof file, "%s_chessboard%02zu.png", name.c_str(), i);
      images.push_back(lens.captures_dir / file);
      if (!cv::imwrite(images.back().string(), gray)) {
        throw std::runtime_error("cannot write " + images.back().string());
      }
    }
    CalibrationPattern pattern;
    pattern.columns = board_scene.chessboard->config().inner_columns;
    pattern.rows = board_scene.chessboard->config().inner_rows;
    pattern.square_mm = board_scene.chessboard->config().square_mm;
    const IntrinsicsResult result = CalibrateIntrinsics(images, pattern);
    // Written beside and renamed, so a test running alongside never reads half a file.
    const fs::path partial =
        lens.intrinsics_json.string() + ".partial." + std::to_string(::getpid());
    std::ofstream(partial) << IntrinsicsToJson(result).dump(1) << "\n";
    fs::rename(partial, lens.intrinsics_json);
    std::ofstream(key_file) << key.dump() << "\n";
  }
  const LensCalibration read = ReadLensJson(lens.intrinsics_json);
  lens.intrinsics = read.intrinsics;
  lens.support_px = read.support_px;
  return lens;
}

}  // namespace mirrorscan::test_support

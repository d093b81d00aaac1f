// The factory calibration (a lens calibration from chessboard captures, then the target)
// against the virtual cabinet's truth where the scanner uses it: at every stripe point of
// whole sweeps of the mannequin and the cuboid, both cameras, every view. The calibrator's
// own residuals are not the measure; the scene's true projection and laser planes are.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "host/board/board_json.h"
#include "host/calibration/calibrate.h"
#include "tests/support/calibration_truth.h"

namespace mirrorscan {
namespace {

using calibration::CalibrationResult;
using calibration::CameraImage;
using test_support::ViewAgreement;
using virtual_cabinet::Scene;

const std::string kSource = MIRRORSCAN_SOURCE_DIR;
// Every third frame of each 300-frame sweep: ~220k points per scene, all columns.
constexpr int kFrameStep = 3;

Scene LoadScene(const std::string& name, const nlohmann::json& patch = nlohmann::json::object()) {
  nlohmann::json json = JsonReader::ParseFile(kSource + "/boards/virtual/scenes/" + name);
  json.merge_patch(patch);
  return Scene::Parse(json, name, kSource + "/boards/virtual/scenes");
}

// The target captures of the calibration scene (with `patch`), each camera with its lens
// from the chessboard step unless `with_lens` is false.
std::vector<CameraImage> TargetImages(const nlohmann::json& patch, bool with_lens,
                                      const std::vector<std::string>& only = {}) {
  const Scene scene = LoadScene("calibration.json", patch);
  const virtual_cabinet::Renderer renderer(scene);
  std::vector<CameraImage> images;
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    if (!only.empty() && std::find(only.begin(), only.end(), scene.cameras[c].name) == only.end())
      continue;
    const auto frame = renderer.RenderFrame(static_cast<int>(c), 0.0, 1, /*lasers_on=*/false);
    const cv::Mat gray(frame.height, frame.width, CV_8UC1,
                       const_cast<uint8_t*>(frame.pixels.data()));
    CameraImage image{scene.cameras[c].name, gray.clone(), std::nullopt, {}};
    if (with_lens) {
      const auto lens = test_support::LensOf(scene, static_cast<int>(c));
      image.lens = lens.intrinsics;
      image.lens_support_px = lens.support_px;
    }
    images.push_back(image);
  }
  return images;
}

calibration::CalibrationSettings Settings() {
  auto settings = host_board::CalibrationSettingsFromBoard(kSource + "/boards/virtual/board.json");
  settings.limits.min_lens_coverage = 0.85;
  return settings;
}

struct Sweep {
  std::string name;
  Scene scene;
  std::vector<test_support::TruthSample> truth;
};

const std::vector<Sweep>& Sweeps() {
  static const std::vector<Sweep> sweeps = [] {
    std::vector<Sweep> s;
    for (const char* name : {"mannequin.json", "cuboid.json"}) {
      Scene scene = LoadScene(name);
      auto truth = test_support::SweepTruth(scene, kFrameStep);
      s.push_back({name, std::move(scene), std::move(truth)});
    }
    return s;
  }();
  return sweeps;
}

std::vector<ViewAgreement> Compare(const Calibration& estimate, const Sweep& sweep) {
  const auto rows = test_support::CompareWithTruth(estimate, sweep.scene, sweep.truth);
  std::printf("%s:\n%s", sweep.name.c_str(), test_support::FormatAgreement(rows).c_str());
  return rows;
}

// Per camera and view: 0.07 px RMS / 0.15 px max, and the millimetre bounds given (each
// call says what they were measured at).
void ExpectWithinBounds(const std::vector<ViewAgreement>& rows, const std::string& where,
                        double max_rms_mm, double max_mm) {
  for (const ViewAgreement& r : rows) {
    const std::string what = where + " " + r.camera + " " + r.view;
    EXPECT_GT(r.points, 1000u) << what;
    EXPECT_LE(r.rms_px, 0.07) << what;  // measured up to 0.061 (one camera, the cuboid)
    EXPECT_LE(r.max_px, 0.15) << what;
    EXPECT_LE(r.rms_mm, max_rms_mm) << what;
    EXPECT_LE(r.max_mm, max_mm) << what;
  }
}

Calibration Truth() {
  return Calibration::Parse(LoadScene("calibration.json").TrueCalibration(), "truth");
}

TEST(CalibrationTruth, TheCamerasWithTheirLensesHoldOverWholeSweeps) {
  const CalibrationResult result =
      calibration::Calibrate(TargetImages(nlohmann::json::object(), true), Settings());
  for (const auto& f : result.failures) std::printf("failure: %s\n", f.c_str());
  ASSERT_TRUE(result.ok);
  for (const auto& c : result.cameras) EXPECT_GE(c.coverage.fraction, 0.85) << c.name;
  test_support::ExpectParametersMatchTruth(*result.calibration, Truth());
  for (const Sweep& sweep : Sweeps())
    // Measured up to 0.363 mm RMS (0.017 px), 1.53 mm max: the lower camera's left view and
    // centre view, whose rays at the top of its image meet the laser planes at 3-10° in the
    // cabinet for people. With the upper and lower camera alone 0.289 mm RMS, 1.92 mm max
    // (0.242 / 1.37 mm from 5°; 0.074 / 0.254 mm in the mannequin's cabinet, f 1400 px,
    // its image ending lower). The left view's rise with the third camera in the fit is
    // 0.017 px RMS magnified by those flat rays; where it comes from is not looked into.
    ExpectWithinBounds(Compare(*result.calibration, sweep), sweep.name, 0.40, 2.1);
}

TEST(CalibrationTruth, OneCameraWithItsLensHoldsOverWholeSweeps) {
  const CalibrationResult result =
      calibration::Calibrate(TargetImages(nlohmann::json::object(), true, {"upper"}), Settings());
  for (const auto& f : result.failures) std::printf("failure: %s\n", f.c_str());
  ASSERT_TRUE(result.ok);
  ASSERT_EQ(result.calibration->cameras.size(), 1u);
  test_support::ExpectParametersMatchTruth(*result.calibration, Truth());
  for (const Sweep& sweep : Sweeps())
    // One camera alone holds its pose with half the target's views: measured up to
    // 0.145 mm RMS, 0.50 mm max (the cuboid's centre view; 0.116 / 0.284 mm in the
    // mannequin's cabinet).
    ExpectWithinBounds(Compare(*result.calibration, sweep), sweep.name, 0.17, 0.6);
}

// The target alone fits its markers to 0.03 px but not the lens beyond them: the coverage
// check refuses it, and the sweep shows why (the bounds above would fail on it).
TEST(CalibrationTruth, TargetAloneIsRefusedAndIsOffWhereTheMarkersAreNot) {
  const CalibrationResult refused =
      calibration::Calibrate(TargetImages(nlohmann::json::object(), false), Settings());
  EXPECT_FALSE(refused.ok);
  bool named = false;
  for (const auto& f : refused.failures)
    named = named || f.find("lens model rests on data") != std::string::npos;
  EXPECT_TRUE(named);
  for (const auto& c : refused.cameras) EXPECT_LT(c.coverage.fraction, 0.5) << c.name;
  calibration::CalibrationSettings lenient = Settings();
  lenient.limits.min_lens_coverage = 0.0;
  const CalibrationResult result =
      calibration::Calibrate(TargetImages(nlohmann::json::object(), false), lenient);
  ASSERT_TRUE(result.ok);
  double worst_px = 0.0;
  for (const ViewAgreement& r : Compare(*result.calibration, Sweeps()[0])) {
    worst_px = std::max(worst_px, r.max_px);
  }
  EXPECT_GT(worst_px, 0.15);
}

// The paper's hall mirror: 1 mm of bump in the right mirror. No plane fits it: the right
// view's residual on the target shows it, and the check refuses the calibration.
TEST(CalibrationTruth, BumpedRightMirrorIsWorseOnItsSide) {
  const nlohmann::json bump = {{"mirrors", {{"right_bump_mm", 1.0}}},
                               {"lasers", {{"emitter_mm", {0, -900}}}}};
  const CalibrationResult result = calibration::Calibrate(TargetImages(bump, true), Settings());
  for (const auto& f : result.failures) std::printf("failure: %s\n", f.c_str());
  ASSERT_TRUE(result.calibration);
  for (const auto& c : result.cameras) {
    std::printf("camera %s: target RMS left %.4f px, right %.4f px\n", c.name.c_str(),
                c.views[1].rms_after_px, c.views[2].rms_after_px);
    EXPECT_GT(c.views[2].rms_after_px, 1.5 * c.views[1].rms_after_px) << c.name;
  }
  // The report's residual check flags the bumped side, not the flat one.
  bool right_flagged = false, left_flagged = false;
  for (const auto& f : result.failures) {
    right_flagged = right_flagged || f.find("right view: markers lie") != std::string::npos;
    left_flagged = left_flagged || f.find("left view: markers lie") != std::string::npos;
  }
  EXPECT_TRUE(right_flagged);
  EXPECT_FALSE(left_flagged);
  EXPECT_FALSE(result.ok);
  // Had it been kept: over a sweep of the bumped cabinet no plane stands in for the bumped
  // mirror, and fitting one pulls the poses and the other mirror along, so every view is
  // off, the right ones most (docs/calibration.md's table: 0.87 px RMS there, 2.4 mm).
  // Every 30th frame: the bumped mirror's truth takes ~2.4 s a frame (its light and images
  // are solved, not reflected), and the right views still get ~3,000 points each.
  const Scene bumped = LoadScene("mannequin.json", bump);
  constexpr int kBumpedFrameStep = 30;
  const auto rows = test_support::CompareWithTruth(
      *result.calibration, bumped, test_support::SweepTruth(bumped, kBumpedFrameStep));
  std::printf("bumped mannequin:\n%s", test_support::FormatAgreement(rows).c_str());
  for (const std::string camera : {"upper", "lower"}) {
    const auto row = [&](const std::string& view) {
      const auto found = std::find_if(rows.begin(), rows.end(), [&](const ViewAgreement& r) {
        return r.camera == camera && r.view == view;
      });
      return found == rows.end() ? ViewAgreement{} : *found;
    };
    ASSERT_GT(row("right").points, 1000u) << camera;
    EXPECT_GT(row("right").rms_px, 2.0 * row("left").rms_px) << camera;
    EXPECT_GT(row("right").rms_px, 0.3) << camera;  // ten times what a flat cabinet reaches
    EXPECT_GT(row("right").max_mm, 1.0) << camera;
  }
}

}  // namespace
}  // namespace mirrorscan

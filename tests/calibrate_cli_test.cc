// mirrorscan calibrate-intrinsics and calibrate-lasers end to end: files written, figures
// against published and simulated truth, one clear line on bad input.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/config/json_reader.h"
#include "host/calibration/intrinsics.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;

using Result = test_support::CommandResult;
using test_support::RunMirrorscan;

const fs::path kSamples = "/usr/share/doc/opencv-doc/examples/data";

TEST(CalibrateCli, IntrinsicsOfOpenCvSamples) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_calibrate_cli_test_intrinsics");
  std::vector<fs::path> images;
  std::string arguments;
  for (int i : {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14}) {
    char name[16];
    std::snprintf(name, sizeof(name), "left%02d.jpg", i);
    images.push_back(kSamples / name);
    arguments += " " + images.back().string();
  }
  ASSERT_TRUE(fs::exists(images[0])) << "install opencv-doc (scripts/setup)";
  const Result r = RunMirrorscan("calibrate-intrinsics --chessboard 9x6 --square 25" + arguments +
                                 " --out " + (dir / "intrinsics.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("[13/13]"), std::string::npos) << r.out;  // progress
  // Against the intrinsics OpenCV ships beside the images (left_intrinsics.yml: fx = fy =
  // 535.9, cx 342.3, cy 235.6, RMS 0.39 px, fixed aspect ratio).
  const nlohmann::json json = JsonReader::ParseFile(dir / "intrinsics.json");
  EXPECT_NEAR(json["camera_matrix"][0][0].get<double>(), 535.9, 0.01 * 535.9);
  EXPECT_NEAR(json["camera_matrix"][1][1].get<double>(), 535.9, 0.01 * 535.9);
  EXPECT_NEAR(json["camera_matrix"][0][2].get<double>(), 342.3, 3.0);
  EXPECT_NEAR(json["camera_matrix"][1][2].get<double>(), 235.6, 3.0);
  EXPECT_LT(json["rms_px"].get<double>(), 0.5);
  EXPECT_EQ(json["images"].size(), 13u);
  fs::remove_all(dir);
}

TEST(CalibrateCli, IntrinsicsBadInputIsOneClearLine) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_calibrate_cli_test_intrinsics_bad");
  const fs::path blank = dir / "blank.png";
  cv::imwrite(blank.string(), cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
  const std::string out = " --out " + (dir / "i.json").string();
  Result r = RunMirrorscan("calibrate-intrinsics --chessboard 9x6 --square 25 " +
                           (kSamples / "left01.jpg").string() + " " + blank.string() + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("\nmirrorscan: " + blank.string() + ": no 9x6 chessboard found\n"),
            std::string::npos)
      << r.out;
  r = RunMirrorscan("calibrate-intrinsics --chessboard 9x6 --charuco 5x7 --square 25 " +
                    blank.string() + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.out,
            "mirrorscan: give exactly one of --chessboard COLSxROWS or --charuco COLSxROWS\n");
  EXPECT_FALSE(fs::exists(dir / "i.json"));
  fs::remove_all(dir);
}

TEST(CalibrateCli, LasersOfASimulatedScan) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_calibrate_cli_test_lasers");
  // The mannequin with a fast slide, so that 15 frames (0.47 s) take the lasers past both
  // cameras' views of the panels.
  const std::string scene = (dir / "fast.json").string();
  std::ofstream(scene) << R"({"subject": {"type": "mannequin"}, "lasers": {"speed_mm_s": 2400},
                             "frames": 300, "seed": 1})";
  ASSERT_EQ(RunMirrorscan("sim scan --scene " + scene + " --frames 15 --no-images --out " +
                          dir.string() + " --peaks " + (dir / "scan.mscan").string())
                .exit_code,
            0);
  const Result r = RunMirrorscan("calibrate-lasers " + (dir / "scan.mscan").string() +
                                 " --calibration " + (dir / "calibration.json").string() +
                                 " --out " + (dir / "lasers.json").string() +
                                 " --calibration-out " + (dir / "fitted.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json lasers = JsonReader::ParseFile(dir / "lasers.json");
  ASSERT_EQ(lasers["frames"].size(), 45u);  // 15 instants, 3 cameras
  for (const nlohmann::json& frame : lasers["frames"]) {
    const double t = frame["time_s"].get<double>();
    for (int k = 0; k < 3; ++k) {
      // The scene's lasers: -50 mm at t = 0, 2400 mm/s, 200 mm apart; within 0.2 mm, as the
      // panels fix the tilt about x (0.17 mm here, laser_height_test's kHeightMaxMm).
      EXPECT_NEAR(frame["heights_mm"][k].get<double>(), -50.0 + 2400.0 * t + 200.0 * k, 0.2);
    }
  }
  EXPECT_LT(lasers["residual_rms_mm"].get<double>(), 0.1);
  EXPECT_LT(lasers["residual_max_mm"].get<double>(), 0.5);
  EXPECT_TRUE(lasers["warnings"].empty()) << lasers["warnings"];
  const nlohmann::json fitted = JsonReader::ParseFile(dir / "fitted.json");
  EXPECT_NEAR(fitted["lasers"]["speed_mm_s"].get<double>(), 2400.0, 0.1);
  // The measured laser offsets, and the readback offset (the sim's readback is laser 0).
  ASSERT_EQ(fitted["lasers"]["offsets_mm"].size(), 3u);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(fitted["lasers"]["offsets_mm"][k].get<double>(), 200.0 * k, 0.1);
  EXPECT_NEAR(fitted["lasers"]["readback_offset_mm"].get<double>(), 0.0, 0.2);
  // Two cameras measure the panels 6 mm behind their mirrors; the fitted calibration keeps
  // what was measured.
  EXPECT_TRUE(lasers["ok"].get<bool>());
  ASSERT_EQ(lasers["panel_offsets"].size(), 2u);
  for (int side = 0; side < 2; ++side) {
    const nlohmann::json& offset = lasers["panel_offsets"][side];
    EXPECT_NEAR(offset["measured_mm"].get<double>(), 6.0, 0.1) << offset;
    EXPECT_TRUE(offset["ok"].get<bool>());
    EXPECT_EQ(fitted["mirrors"][side]["panel_offset_mm"].get<double>(),
              offset["measured_mm"].get<double>());
  }

  // The calibration says the panels stand 9 mm back; they stand 6: a clear failure, the
  // measurement in lasers.json, no calibration written.
  nlohmann::json moved = JsonReader::ParseFile(dir / "calibration.json");
  for (auto& mirror : moved["mirrors"]) mirror["panel_offset_mm"] = 9.0;
  moved.erase("content_hash");
  std::ofstream(dir / "moved.json") << moved.dump();
  const Result off = RunMirrorscan(
      "calibrate-lasers " + (dir / "scan.mscan").string() + " --calibration " +
      (dir / "moved.json").string() + " --board " + std::string(MIRRORSCAN_SOURCE_DIR) +
      "/boards/virtual/board.json --out " + (dir / "moved-lasers.json").string() +
      " --calibration-out " + (dir / "moved-fitted.json").string());
  EXPECT_EQ(off.exit_code, 1) << off.out;
  const std::string measured = "calibrate-lasers: FAIL: left panel: measured ";
  const size_t at = off.out.find(measured);
  ASSERT_NE(at, std::string::npos) << off.out;
  EXPECT_NEAR(std::stod(off.out.substr(at + measured.size())), 6.0, 0.05) << off.out;
  EXPECT_NE(off.out.find("the calibration says 9.00 mm (limit ± 1 mm): check how the panel is "
                         "mounted"),
            std::string::npos)
      << off.out;
  EXPECT_NE(off.out.find("FAIL: right panel"), std::string::npos) << off.out;
  EXPECT_NE(off.out.find("no calibration written"), std::string::npos) << off.out;
  EXPECT_FALSE(fs::exists(dir / "moved-fitted.json"));
  const nlohmann::json moved_lasers = JsonReader::ParseFile(dir / "moved-lasers.json");
  EXPECT_FALSE(moved_lasers["ok"].get<bool>());
  EXPECT_EQ(moved_lasers["failures"].size(), 2u);
  EXPECT_NEAR(moved_lasers["panel_offsets"][0]["measured_mm"].get<double>(), 6.0, 0.1);

  // A calibration whose mirrors have no corners cannot say where the panels are.
  nlohmann::json calibration = JsonReader::ParseFile(dir / "calibration.json");
  for (auto& mirror : calibration["mirrors"]) mirror.erase("corners_mm");
  calibration.erase("content_hash");  // edited by hand: no hash to check
  std::ofstream(dir / "no_corners.json") << calibration.dump();
  const Result bad =
      RunMirrorscan("calibrate-lasers " + (dir / "scan.mscan").string() + " --calibration " +
                    (dir / "no_corners.json").string() + " --out " + (dir / "x.json").string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_EQ(bad.out, "mirrorscan: " + (dir / "no_corners.json").string() +
                         ": mirrors[0].corners_mm: the laser fit needs the mirror's 4 corners\n");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mirrorscan

#include "host/board/board_json.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "boards/virtual/scene.h"
#include "common/config/json_reader.h"

namespace mirrorscan::host_board {
namespace {

using virtual_cabinet::Scene;

TEST(BoardJson, BoundingCylinderFromBoard) {
  const auto path = std::filesystem::temp_directory_path() / "reconstruct_test_board.json";
  std::ofstream(path) << R"({"board": "x", "reconstruction": {"bounding_cylinder":
      {"radius_mm": 300, "top_mm": 1900}}})";
  const reconstruction::BoundingCylinder c = BoundingCylinderFromBoard(path);
  EXPECT_EQ(c.radius_mm, 300);
  EXPECT_EQ(c.top_mm, 1900);
  EXPECT_EQ(c.bottom_mm, reconstruction::BoundingCylinder().bottom_mm);
  EXPECT_TRUE(c.Contains({0, 299, 1000}));
  EXPECT_FALSE(c.Contains({0, 301, 1000}));
  // The core is never wider than the cylinder.
  EXPECT_EQ(c.core_radius_mm, 300);
  EXPECT_TRUE(c.OnFloor({0, 100, 5}));
  EXPECT_FALSE(c.OnFloor({0, 100, 30}));
  std::ofstream(path) << R"({"reconstruction": {"bounding_cylinder": {"radius_mm": 300,
      "core_radius_mm": 400}}})";
  try {
    BoundingCylinderFromBoard(path);
    FAIL() << "accepted a core wider than the cylinder";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("core_radius_mm"), std::string::npos) << e.what();
  }
  std::ofstream(path) << R"({"reconstruction": {"bounding_cylinder": {"radius": 300}}})";
  try {
    BoundingCylinderFromBoard(path);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("radius"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

TEST(BoardJson, CalibrationSettingsNameTheKey) {
  const std::string source = MIRRORSCAN_SOURCE_DIR;
  nlohmann::json board = JsonReader::ParseFile(source + "/boards/virtual/board.json");
  board["calibration"] = {{"limits", {{"max_rms_px", -1}}}};
  try {
    ParseCalibrationSettings(board, "board.json");
    FAIL() << "accepted a negative limit";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "board.json: calibration.limits.max_rms_px: must be in [0.001, 100], got -1");
  }
  EXPECT_EQ(CalibrationSettingsFromBoard(source + "/boards/virtual/board.json").camera_names,
            (std::vector<std::string>{"upper", "lower", "up"}));
}

TEST(BoardJson, PeakParamsFromBoard) {
  const std::string source = MIRRORSCAN_SOURCE_DIR;
  const PeakParams virtual_board = PeakParamsFromBoard(source + "/boards/virtual/board.json");
  EXPECT_EQ(virtual_board.estimator, PeakEstimator::kAdaptive);
  EXPECT_EQ(virtual_board.threshold_dn, 10);
  EXPECT_EQ(virtual_board.dim_peak_dn, 18);
  EXPECT_EQ(virtual_board.dim_stripe_min_columns, 7);
  EXPECT_EQ(virtual_board.max_peaks_per_column, 9);
  const auto path = std::filesystem::temp_directory_path() / "host_board_peaks.json";
  std::ofstream(path) << R"({"board": "x"})";
  EXPECT_EQ(PeakParamsFromBoard(path).threshold_dn, PeakParams().threshold_dn);
  std::ofstream(path) << R"({"peaks": {"threshold_dn": 300}})";
  try {
    PeakParamsFromBoard(path);
    FAIL() << "accepted a threshold above 254";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string() + ": peaks.threshold_dn"), std::string::npos)
        << e.what();
  }
  std::filesystem::remove(path);
}

TEST(BoardJson, ReachFromBoard) {
  const std::string source = MIRRORSCAN_SOURCE_DIR;
  const nlohmann::json shipped = JsonReader::ParseFile(source + "/boards/virtual/board.json");
  const BoardReach virtual_board = ReachFromBoard(source + "/boards/virtual/board.json");
  ASSERT_TRUE(virtual_board.sweep_end_mm && virtual_board.mirror_top_mm);
  EXPECT_EQ(*virtual_board.sweep_end_mm, shipped["scan"]["sweep_end_mm"].get<double>());
  EXPECT_EQ(*virtual_board.mirror_top_mm,
            shipped["calibration"]["mirror_bottom_mm"].get<double>() +
                shipped["calibration"]["mirror_height_mm"].get<double>());
  const auto path = std::filesystem::temp_directory_path() / "host_board_reach.json";
  std::ofstream(path) << R"({"board": "x", "calibration": {"mirror_height_mm": 1500}})";
  const BoardReach silent = ReachFromBoard(path);
  EXPECT_FALSE(silent.sweep_end_mm);
  EXPECT_FALSE(silent.mirror_top_mm) << "no default stands in for a mirror the board omits";
  std::ofstream(path) << R"({"scan": {"sweep_end_mm": "high"}})";
  EXPECT_THROW(ReachFromBoard(path), ConfigError);
  std::filesystem::remove(path);
}

// Every shipped board carries the cabinet's cylinder: it holds the A-pose mannequin whole,
// hands (619 mm out) and head, and its core, where one hypothesis decides a peak alone,
// holds the torso above the hands and stays in front of both mirrors.
TEST(BoardJson, ShippedBoardsCarryTheCabinetsCylinder) {
  const std::string source = MIRRORSCAN_SOURCE_DIR;
  const Scene scene = Scene::Load(source + "/boards/virtual/scenes/mannequin.json");
  for (const char* board : {"virtual", "rpi4", "rpi5"}) {
    const std::string path = source + "/boards/" + board + "/board.json";
    ASSERT_TRUE(JsonReader::ParseFile(path).contains("reconstruction")) << path;
    const reconstruction::BoundingCylinder c = BoundingCylinderFromBoard(path);
    double radius = 0, top = 0, torso = 0;
    for (const Eigen::Vector3d& v : scene.subject.mesh.vertices) {
      const double r = (v.head<2>() - c.center_mm).norm();
      radius = std::max(radius, r);
      top = std::max(top, v.z());
      if (v.z() > 1200) torso = std::max(torso, r);  // above the hands
    }
    std::printf(
        "%s: radius %.0f mm, core %.0f mm; the mannequin reaches %.1f mm out (%.1f above 1200 "
        "mm), %.1f mm high\n",
        board, c.radius_mm, c.core_radius_mm, radius, torso, top);
    EXPECT_LT(radius + 10, c.radius_mm) << board;
    EXPECT_LT(torso + 10, c.core_radius_mm) << board;
    EXPECT_LT(top, c.top_mm) << board;
    for (const auto& mirror : scene.mirrors) {
      EXPECT_GT(mirror.plane.SignedDistance(Eigen::Vector3d(c.center_mm.x(), c.center_mm.y(), 0)),
                c.core_radius_mm)
          << board << ": the core reaches behind a mirror";
    }
  }
}

}  // namespace
}  // namespace mirrorscan::host_board

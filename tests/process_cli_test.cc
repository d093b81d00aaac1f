// `mirrorscan process` and `mirrorscan mesh` end to end on sweeps of the virtual cabinet:
// the outputs and summary of a mannequin scan; exit 1 with a reason and no mesh for scans
// that cannot give a body; exit 2 for usage errors.
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/config/json_reader.h"
#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using Result = test_support::CommandResult;
using test_support::RunMirrorscan;
using test_support::VirtualScene;

// A whole sweep of `scene` (changes merged into the mannequin scene) reduced to peaks in
// dir/scan.mscan, with the scene's true calibration in dir/calibration.json.
void SimulateScan(const fs::path& dir, const nlohmann::json& changes) {
  nlohmann::json scene = JsonReader::ParseFile(VirtualScene("mannequin"));
  scene.merge_patch(changes);
  std::ofstream(dir / "scene.json") << scene.dump();
  const Result r =
      RunMirrorscan("sim scan --scene " + (dir / "scene.json").string() + " --out " +
                    (dir / "sweep").string() + " --no-images --board " + MIRRORSCAN_SOURCE_DIR +
                    "/boards/virtual/board.json --peaks " + (dir / "scan.mscan").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  fs::copy_file(dir / "sweep" / "calibration.json", dir / "calibration.json");
}

std::string Process(const fs::path& dir, const std::string& extra = "") {
  return "process " + (dir / "scan.mscan").string() + " --calibration " +
         (dir / "calibration.json").string() + " --out " + (dir / "out").string() + " " + extra;
}

class ProcessCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(test_support::FreshTempDir("mirrorscan_process_cli"));
    SimulateScan(*dir_, nlohmann::json::object());
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static fs::path* dir_;
};
fs::path* ProcessCli::dir_ = nullptr;

TEST_F(ProcessCli, MannequinScanGivesMeshPreviewsAndSummary) {
  const fs::path out = *dir_ / "out";
  // A stale mesh from an earlier job must not survive.
  fs::create_directories(out);
  std::ofstream(out / "mesh.stl") << "stale";
  const Result r = RunMirrorscan(Process(*dir_, "--formats ply,obj --preview-height 300"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const char* name :
       {"points.ply", "mesh.ply", "mesh.obj", "summary.json", "measurements.json",
        "preview-measurements.png", "preview-front.png", "preview-back.png", "preview-left.png",
        "preview-right.png", "preview-cloud-views.png", "preview-cloud-cameras.png"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  EXPECT_FALSE(fs::exists(out / "mesh.stl"));
  const cv::Mat front = cv::imread((out / "preview-front.png").string());
  EXPECT_EQ(front.rows, 300);

  const nlohmann::json summary = JsonReader::ParseFile(out / "summary.json");
  EXPECT_TRUE(summary["ok"].get<bool>());
  EXPECT_EQ(summary["inputs"]["archive"]["sha256"].get<std::string>().size(), 64u);
  const Result sha = test_support::RunCommandMerged("sha256sum " + (*dir_ / "scan.mscan").string());
  EXPECT_EQ(sha.out.substr(0, 64), summary["inputs"]["archive"]["sha256"].get<std::string>());
  EXPECT_EQ(summary["versions"]["open3d"], "0.16.1");
  EXPECT_GT(summary["reconstruction"]["points"].get<int>(), 100000);
  const nlohmann::json& mesh = summary["mesh"];
  EXPECT_GT(mesh["triangles"].get<int>(), 100000);
  EXPECT_GT(mesh["holes"]["count"].get<int>(), 0);
  // The mannequin stands on the floor and is 1750 mm tall.
  EXPECT_NEAR(mesh["bounds_mm"]["max"][2].get<double>(), 1750.0, 10.0);
  EXPECT_LT(mesh["bounds_mm"]["min"][2].get<double>(), 60.0);
  for (const char* stage : {"read", "reconstruct", "mesh", "mesh.poisson", "previews", "total"}) {
    EXPECT_TRUE(summary["timings_s"].contains(stage)) << stage;
  }
  EXPECT_TRUE(summary.contains("measurements"));

  // The measurements of the scanned surface against the mannequin's analytic truth (the
  // sim's, not the measuring code's): each value within the bounds (girths 3 mm,
  // heights and lengths 2 mm) or withheld with a reason; never a number where the scan
  // has none. Waist and hip are seen whole on this scan and must be given.
  const Result truth_run = RunMirrorscan("sim subject --scene " + VirtualScene("mannequin") +
                                         " --out " + (*dir_ / "subject.ply").string() +
                                         " --truth " + (*dir_ / "truth.json").string());
  ASSERT_EQ(truth_run.exit_code, 0) << truth_run.out;
  const nlohmann::json truth = JsonReader::ParseFile(*dir_ / "truth.json").at("truth");
  const nlohmann::json measured = JsonReader::ParseFile(out / "measurements.json");
  ASSERT_GE(measured.at("measurements").size(), 10u);
  std::set<std::string> given;
  for (const nlohmann::json& m : measured.at("measurements")) {
    const std::string name = m.at("name");
    if (!m.at("withheld").is_null()) {
      EXPECT_FALSE(m.at("withheld").get<std::string>().empty()) << name;
      EXPECT_TRUE(m.at("value_mm").is_null()) << name;
      continue;
    }
    given.insert(name);
    std::string key = name;
    for (const std::string side : {"_left", "_right"}) {
      if (key.size() > side.size() && key.ends_with(side)) key.resize(key.size() - side.size());
    }
    ASSERT_TRUE(truth.contains(key + "_mm")) << name;
    const double bound = name.find("girth") != std::string::npos ? 3.0 : 2.0;
    EXPECT_NEAR(m.at("value_mm").get<double>(), truth.at(key + "_mm").get<double>(), bound) << name;
  }
  EXPECT_TRUE(given.count("waist_girth") && given.count("hip_girth"));
}

TEST_F(ProcessCli, MeshCommandMeshesTheCloud) {
  const fs::path out = *dir_ / "mesh-command";
  fs::create_directories(out);
  if (!fs::exists(*dir_ / "out" / "points.ply")) {
    ASSERT_EQ(RunMirrorscan(Process(*dir_, "--no-previews")).exit_code, 0);
  }
  const Result r = RunMirrorscan("mesh " + (*dir_ / "out" / "points.ply").string() + " --out " +
                                 (out / "m.ply").string() + " --formats stl --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(fs::exists(out / "m.ply"));
  EXPECT_TRUE(fs::exists(out / "m.stl"));
}

TEST_F(ProcessCli, UsageErrorsExit2) {
  const fs::path out = *dir_ / "usage";
  Result r = RunMirrorscan("process " + (*dir_ / "missing.mscan").string() + " --calibration " +
                           (*dir_ / "calibration.json").string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("missing.mscan: no such file"), std::string::npos) << r.out;
  r = RunMirrorscan(Process(*dir_, "--formats ply,fbx"));
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("\"fbx\" is not one of ply, obj, stl"), std::string::npos) << r.out;
  r = RunMirrorscan("process --calibration x.json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  std::ofstream(*dir_ / "not-calibration.json") << "{\"version\": 1}";
  r = RunMirrorscan("process " + (*dir_ / "scan.mscan").string() + " --calibration " +
                    (*dir_ / "not-calibration.json").string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("not-calibration.json"), std::string::npos) << r.out;
}

// A scan that cannot give a body: exit 1, the reason on stderr and in summary.json, no mesh.
void ExpectNoBody(const fs::path& dir, const std::string& reason) {
  const Result r = RunMirrorscan(Process(dir));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find(reason), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "out" / "mesh.ply"));
  EXPECT_FALSE(fs::exists(dir / "out" / "preview-front.png"));
  const nlohmann::json summary = JsonReader::ParseFile(dir / "out" / "summary.json");
  EXPECT_FALSE(summary["ok"].get<bool>());
  EXPECT_NE(summary["reason"].get<std::string>().find(reason), std::string::npos);
}

TEST(ProcessCliNoBody, EmptyCabinetExits1) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_process_empty");
  SimulateScan(dir, {{"subject", {{"type", "none"}}}, {"frames", 150}});
  ExpectNoBody(dir, "no usable points");
  fs::remove_all(dir);
}

TEST(ProcessCliNoBody, CloudOfOneViewExits1) {
  // Black mirrors: the camera sees the mannequin's front only.
  const fs::path dir = test_support::FreshTempDir("mirrorscan_process_one_view");
  SimulateScan(dir, {{"mirrors", {{"reflectivity", 0.0}}}, {"frames", 150}});
  ExpectNoBody(dir, "only the center view");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mirrorscan

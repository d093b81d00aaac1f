// `mirrorscan sim subject` and `mirrorscan measure` end to end: the exact mannequin
// surface written as PLY and STL, measured against the truth the sim writes beside it;
// a cylinder withheld; bad input gives one clear line.
#include <filesystem>
#include <fstream>
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

const nlohmann::json& Find(const nlohmann::json& measurements, const std::string& name) {
  for (const nlohmann::json& m : measurements.at("measurements")) {
    if (m.at("name") == name) return m;
  }
  throw std::runtime_error("no measurement " + name);
}

TEST(MeasureCliTest, MannequinAgainstTheSimsTruth) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_measure_cli");
  const fs::path mesh = dir / "mannequin.ply", truth_file = dir / "truth.json";
  Result r = RunMirrorscan("sim subject --scene " + VirtualScene("mannequin") + " --out " +
                           mesh.string() + " --truth " + truth_file.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json truth = JsonReader::ParseFile(truth_file).at("truth");
  r = test_support::RunCommand(std::string(MIRRORSCAN_BIN_DIR) + "/mirrorscan measure " +
                                   mesh.string() + " --out " + (dir / "m.json").string() +
                                   " --csv " + (dir / "m.csv").string() + " --preview " +
                                   (dir / "m.png").string() + " --girth-at 1000,500 --json",
                               dir / "err.txt");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json written = JsonReader::ParseFile(dir / "m.json");
  EXPECT_EQ(nlohmann::json::parse(r.out), written);  // --json prints what --out holds
  EXPECT_NEAR(written.at("stature_mm").get<double>(), truth.at("stature_mm").get<double>(), 2.0);
  for (const char* girth : {"chest", "waist", "hip", "neck"}) {
    const nlohmann::json& m = Find(written, std::string(girth) + "_girth");
    EXPECT_NEAR(m.at("value_mm").get<double>(),
                truth.at(std::string(girth) + "_girth_mm").get<double>(), 3.0)
        << girth;
    EXPECT_TRUE(m.at("z_mm").is_number());
    EXPECT_TRUE(m.at("withheld").is_null());
  }
  EXPECT_NEAR(Find(written, "arm_length_left").at("value_mm").get<double>(),
              truth.at("arm_length_mm").get<double>(), 2.0);
  // 1000 mm is torso, 500 mm cuts both legs.
  ASSERT_EQ(written.at("slices").size(), 3u);
  EXPECT_EQ(written.at("slices")[0].at("part"), "torso");
  EXPECT_EQ(written.at("slices")[1].at("part"), "left_leg");
  const std::string csv = test_support::ReadFile(dir / "m.csv");
  EXPECT_EQ(csv.rfind("name,value_mm,z_mm,contour_mm,confidence,withheld\n", 0), 0u);
  EXPECT_NE(csv.find("\nchest_girth,"), std::string::npos);
  const cv::Mat preview = cv::imread((dir / "m.png").string());
  ASSERT_FALSE(preview.empty());
  EXPECT_EQ(preview.rows, 1000);

  // The same surface as STL (every triangle's corners stored apart) measures the same.
  ASSERT_EQ(RunMirrorscan("sim subject --scene " + VirtualScene("mannequin") + " --out " +
                          (dir / "mannequin.stl").string())
                .exit_code,
            0);
  r = RunMirrorscan("measure " + (dir / "mannequin.stl").string() + " --out " +
                    (dir / "stl.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json stl = JsonReader::ParseFile(dir / "stl.json");
  EXPECT_NEAR(Find(stl, "waist_girth").at("value_mm").get<double>(),
              truth.at("waist_girth_mm").get<double>(), 3.0);
  fs::remove_all(dir);
}

TEST(MeasureCliTest, CylinderIsWithheldWithTheReason) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_measure_cli_cylinder");
  ASSERT_EQ(RunMirrorscan("sim subject --scene " + VirtualScene("cylinder") + " --out " +
                          (dir / "c.ply").string())
                .exit_code,
            0);
  const Result r =
      RunMirrorscan("measure " + (dir / "c.ply").string() + " --out " + (dir / "c.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("withheld: not a human body"), std::string::npos) << r.out;
  const nlohmann::json json = JsonReader::ParseFile(dir / "c.json");
  EXPECT_TRUE(json.at("stature_mm").is_null());
  for (const nlohmann::json& m : json.at("measurements")) {
    EXPECT_TRUE(m.at("value_mm").is_null()) << m.at("name");
    EXPECT_TRUE(m.at("withheld").is_string()) << m.at("name");
  }
  fs::remove_all(dir);
}

TEST(MeasureCliTest, BadInputGivesOneClearLine) {
  const fs::path dir = test_support::FreshTempDir("mirrorscan_measure_cli_bad");
  Result r = RunMirrorscan("measure " + (dir / "none.ply").string() + " --out " +
                           (dir / "m.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.out, "mirrorscan: " + (dir / "none.ply").string() + ": no such file\n");
  std::ofstream(dir / "notes.txt") << "not a mesh\n";
  r = RunMirrorscan("measure " + (dir / "notes.txt").string() + " --out " +
                    (dir / "m.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("unsupported mesh format"), std::string::npos) << r.out;
  std::ofstream(dir / "broken.ply") << "ply\nformat ascii 1.0\nelement vertex 3\n";
  r = RunMirrorscan("measure " + (dir / "broken.ply").string() + " --out " +
                    (dir / "m.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("broken.ply"), std::string::npos) << r.out;
  r = RunMirrorscan("measure " + (dir / "none.ply").string() + " --out " +
                    (dir / "m.json").string() + " --girth-at 900,abc");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir / "m.json"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mirrorscan

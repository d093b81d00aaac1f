// mirrorscan reconstruct end to end on a short simulated sweep: the PLY and the summary,
// and one clear line (exit 1) for an archive of another calibration, an empty archive and
// a missing camera; a truncated archive is reconstructed as far as it was recovered.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using Result = test_support::CommandResult;

std::string Mirrorscan() { return std::string(MIRRORSCAN_BIN_DIR) + "/mirrorscan"; }

Result RunMirrorscan(const std::string& arguments, const fs::path& dir) {
  return test_support::RunCommand(Mirrorscan() + " " + arguments, dir / "stderr.txt");
}

// The first 120 frames of the mannequin sweep (the legs to the hips), made once: over a
// stretch of 60 the lower camera's view of the shins at its end stays undecided (3,894
// ambiguous peaks against 2 over 120).
const fs::path& Sweep() {
  static const fs::path dir = [] {
    const fs::path d = test_support::FreshTempDir("mirrorscan_reconstruct_cli_test");
    const Result r =
        RunMirrorscan("sim scan --scene " + std::string(MIRRORSCAN_SOURCE_DIR) +
                          "/boards/virtual/scenes/mannequin.json --frames 120 --no-images "
                          "--peaks " +
                          (d / "scan.mscan").string() + " --out " + (d / "sim").string(),
                      d);
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    return d;
  }();
  return dir;
}

TEST(ReconstructCli, WritesThePlyAndTheSummary) {
  const fs::path& d = Sweep();
  const Result r = RunMirrorscan("reconstruct " + (d / "scan.mscan").string() + " --calibration " +
                                     (d / "sim/calibration.json").string() + " --out " +
                                     (d / "points.ply").string() + " --json",
                                 d);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json summary = nlohmann::json::parse(r.out);
  EXPECT_GT(summary["points"].get<size_t>(), 10000u);
  EXPECT_EQ(summary["laser_height"]["source"], "panels");
  EXPECT_LT(
      summary["dropped"]["ambiguous"].get<size_t>() + summary["dropped"]["conflict"].get<size_t>(),
      summary["points"].get<size_t>() / 30)
      << summary.dump(2);
  std::string header = test_support::ReadFile(d / "points.ply");
  header.resize(header.find("end_header"));
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("element vertex " + std::to_string(summary["points"].get<size_t>())),
            std::string::npos);
  for (const char* property : {"nx", "camera", "view", "laser", "frame", "u", "confidence"})
    EXPECT_NE(header.find(std::string(" ") + property + "\n"), std::string::npos) << property;
  // Without --json: the summary as text, progress on stderr.
  const Result text = RunMirrorscan("reconstruct " + (d / "scan.mscan").string() +
                                        " --calibration " + (d / "sim/calibration.json").string() +
                                        " --out " + (d / "points2.ply").string(),
                                    d);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("decided by stereo"), std::string::npos) << text.out;
  EXPECT_NE(text.err.find("reconstruct: triangulation"), std::string::npos) << text.err;
}

TEST(ReconstructCli, AnotherCalibrationIsRefusedUnlessAllowed) {
  const fs::path& d = Sweep();
  nlohmann::json calibration;
  std::ifstream(d / "sim/calibration.json") >> calibration;
  calibration["mirrors"][1]["offset_mm"] =
      calibration["mirrors"][1]["offset_mm"].get<double>() + 1.0;
  calibration.erase("content_hash");  // an edited file, valid but another calibration
  std::ofstream(d / "other.json") << calibration.dump(2);
  const std::string args = "reconstruct " + (d / "scan.mscan").string() + " --calibration " +
                           (d / "other.json").string() + " --out " + (d / "other.ply").string();
  const Result refused = RunMirrorscan(args, d);
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("mirrorscan: calibration mismatch"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("--calibration-mismatch-ok"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(d / "other.ply"));
  // An archive recording the calibration as a device does (its file's SHA-256).
  const Result device_like = RunMirrorscan(
      "sim scan --scene " + std::string(MIRRORSCAN_SOURCE_DIR) +
          "/boards/virtual/scenes/mannequin.json --frames 2 --no-images --calibration " +
          (d / "other.json").string() + " --peaks " + (d / "device.mscan").string() + " --out " +
          (d / "device").string(),
      d);
  ASSERT_EQ(device_like.exit_code, 0) << device_like.err;
  const Result refused_sha = RunMirrorscan(
      "reconstruct " + (d / "device.mscan").string() + " --calibration " +
          (d / "sim/calibration.json").string() + " --out " + (d / "device.ply").string(),
      d);
  EXPECT_EQ(refused_sha.exit_code, 1);
  EXPECT_NE(refused_sha.err.find("calibration_sha256"), std::string::npos) << refused_sha.err;
  const Result allowed = RunMirrorscan(args + " --calibration-mismatch-ok", d);
  EXPECT_EQ(allowed.exit_code, 0) << allowed.err;
  EXPECT_NE(allowed.err.find("warning: calibration mismatch accepted"), std::string::npos)
      << allowed.err;
}

TEST(ReconstructCli, EmptyTruncatedAndMissingCamera) {
  const fs::path& d = Sweep();
  const std::string calibration = " --calibration " + (d / "sim/calibration.json").string();
  std::ofstream(d / "empty.mscan").close();
  const Result empty = RunMirrorscan("reconstruct " + (d / "empty.mscan").string() + calibration +
                                         " --out " + (d / "empty.ply").string(),
                                     d);
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_NE(empty.err.find("mirrorscan: no readable header"), std::string::npos) << empty.err;

  // Cut in the middle of a frame record: the frames before it are used, and that is said.
  const std::string bytes = test_support::ReadFile(d / "scan.mscan");
  std::ofstream(d / "cut.mscan", std::ios::binary) << bytes.substr(0, bytes.size() * 3 / 5);
  const Result cut = RunMirrorscan("reconstruct " + (d / "cut.mscan").string() + calibration +
                                       " --out " + (d / "cut.ply").string() + " --json",
                                   d);
  ASSERT_EQ(cut.exit_code, 0) << cut.err;
  const nlohmann::json summary = nlohmann::json::parse(cut.out);
  EXPECT_FALSE(summary["archive"]["complete"].get<bool>());
  EXPECT_GT(summary["points"].get<size_t>(), 1000u);
  EXPECT_NE(cut.err.find("recovered"), std::string::npos) << cut.err;

  nlohmann::json one_camera;
  std::ifstream(d / "sim/calibration.json") >> one_camera;
  one_camera["cameras"].erase(1);
  one_camera.erase("content_hash");
  std::ofstream(d / "one_camera.json") << one_camera.dump(2);
  const Result missing =
      RunMirrorscan("reconstruct " + (d / "scan.mscan").string() + " --calibration " +
                        (d / "one_camera.json").string() + " --calibration-mismatch-ok --out " +
                        (d / "one.ply").string(),
                    d);
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("camera \"lower\" is not in the calibration"), std::string::npos)
      << missing.err;
}

// A value the reconstruction cannot use is refused with one line naming the option, never
// taken for "not given" and replaced by the default.
TEST(ReconstructCli, BadOptionValuesAreRefused) {
  const fs::path& d = Sweep();
  const std::string base = "reconstruct " + (d / "scan.mscan").string() + " --calibration " +
                           (d / "sim/calibration.json").string() + " --out " +
                           (d / "bad.ply").string();
  for (const std::string option :
       {"--cylinder-radius -5", "--cylinder-radius 0", "--cylinder-core-radius -1",
        "--min-angle 95", "--stereo-max-mm -1", "--prefer-camera -2"}) {
    const Result r = RunMirrorscan(base + " " + option, d);
    EXPECT_NE(r.exit_code, 0) << option;
    const std::string name = option.substr(0, option.find(' '));
    EXPECT_NE(r.err.find(name), std::string::npos) << option << ": " << r.err;
    EXPECT_FALSE(fs::exists(d / "bad.ply")) << option;
  }
}

}  // namespace
}  // namespace mirrorscan

// `mirrorscand --check` on the virtual board: every check passes on a calibrated device,
// and each injected fault (no camera, drive not answering, lasers stuck, no calibration,
// disk full) fails with its own one line and exit status 1 (docs/firmware.md).
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test_support::ChildProcess;
using test_support::ReadFile;

const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

class CheckTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The scene's true calibration (valid by construction), rendered once.
    truth_ = new fs::path(test_support::FreshTempDir("mirrorscand_check_truth"));
    const auto r = test_support::RunCommandMerged(
        std::string(MIRRORSCAN_BIN_DIR) + "/mirrorscan sim render --scene " +
        (kSource / "boards/virtual/scenes/mannequin.json").string() + " --out " + truth_->string());
    ASSERT_EQ(r.exit_code, 0) << r.out;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*truth_);
    delete truth_;
  }
  void SetUp() override {
    dir_ = test_support::FreshTempDir("mirrorscand_check_test");
    fs::create_directories(dir_ / "data");
    fs::copy_file(*truth_ / "calibration.json", dir_ / "data" / "calibration.json");
    board_ = json::parse(ReadFile(kSource / "boards/virtual/board.json"));
    board_["virtual"]["scene"] = (kSource / "boards/virtual/scenes/mannequin.json").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  struct Outcome {
    int exit_code = -1;
    std::vector<std::string> failed;  // the FAIL lines
    std::string output;
  };
  Outcome Check(const std::vector<std::string>& extra = {}, rlim_t file_size_limit = 0) {
    std::ofstream(dir_ / "board.json") << board_.dump(2);
    std::vector<std::string> args = {"--board", (dir_ / "board.json").string(), "--data-dir",
                                     (dir_ / "data").string(), "--check"};
    args.insert(args.end(), extra.begin(), extra.end());
    test_support::ChildOptions options;
    options.file_size_limit = file_size_limit;
    ChildProcess check(MIRRORSCAND_PATH, args, dir_ / "check.log", options);
    Outcome outcome;
    outcome.exit_code = check.Wait(std::chrono::minutes(3));
    outcome.output = check.Log();
    std::istringstream lines(outcome.output);
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("FAIL ", 0) == 0) outcome.failed.push_back(line);
    }
    return outcome;
  }
  static bool Has(const std::string& text, const std::string& words) {
    return text.find(words) != std::string::npos;
  }

  static fs::path* truth_;
  fs::path dir_;
  json board_;
};
fs::path* CheckTest::truth_ = nullptr;

TEST_F(CheckTest, EveryCheckPassesOnTheVirtualBoard) {
  const Outcome o = Check();
  EXPECT_EQ(o.exit_code, 0) << o.output;
  EXPECT_TRUE(o.failed.empty()) << o.output;
  for (const char* name :
       {"ok   drive: answers, homed", "ok   camera upper: present, streaming",
        "ok   camera lower: present, streaming", "ok   camera up: present, streaming",
        "ok   lasers:", "ok   disk:", "ok   calibration:", "ok   clock:",
        "check passed: 8 checks, 0 failed"}) {
    EXPECT_TRUE(Has(o.output, name)) << name << "\n" << o.output;
  }
}

TEST_F(CheckTest, NoCameraFailsOneLine) {
  board_["cameras"][1]["id"] = 7;  // the scene has cameras 0, 1 and 2
  const Outcome o = Check();
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL devices:")) << o.failed[0];
  EXPECT_TRUE(Has(o.failed[0], "lower") || Has(o.failed[0], "camera")) << o.failed[0];
}

TEST_F(CheckTest, ADriveThatDoesNotAnswerFailsOneLine) {
  const Outcome o = Check({"--check-fault", "drive-silent"});
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL drive:")) << o.failed[0];
}

TEST_F(CheckTest, StuckLasersFailOneLine) {
  const Outcome o = Check({"--check-fault", "lasers-stuck"});
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL lasers:")) << o.failed[0];
  EXPECT_TRUE(Has(o.failed[0], "do not go off")) << o.failed[0];
}

TEST_F(CheckTest, NoCalibrationFailsOneLine) {
  fs::remove(dir_ / "data" / "calibration.json");
  const Outcome o = Check();
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL calibration: none stored")) << o.failed[0];
}

TEST_F(CheckTest, AnInvalidCalibrationFailsOneLine) {
  std::ofstream(dir_ / "data" / "calibration.json") << R"({"version": 1})";
  const Outcome o = Check();
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL calibration: invalid")) << o.failed[0];
}

TEST_F(CheckTest, AFullDiskFailsOneLine) {
  // Files may not grow past 64 KiB: the check's 1 MiB write fails as on a full disk.
  const Outcome o = Check({}, 64 << 10);
  EXPECT_EQ(o.exit_code, 1) << o.output;
  ASSERT_EQ(o.failed.size(), 1u) << o.output;
  EXPECT_TRUE(Has(o.failed[0], "FAIL disk: cannot write 1 MiB")) << o.failed[0];
}

}  // namespace
}  // namespace mirrorscan

#include "firmware/service/calibration_store.h"

#include <unistd.h>

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "common/config/json_reader.h"
#include "common/protocol/sha256.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A valid calibration.json of the virtual cabinet (as `mirrorscan calibrate` writes it).
std::string ValidCalibrationText() {
  return ReadFile(fs::path(MIRRORSCAN_SOURCE_DIR) / "firmware/service/testdata/calibration.json");
}

class CalibrationStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(testing::TempDir()) / ("calibration_store_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(CalibrationStoreTest, PutStoresAtomicallyAndSurvivesReopen) {
  const fs::path path = dir_ / "calibration.json";
  CalibrationStore store(path);
  EXPECT_FALSE(store.Get().has_value());
  EXPECT_EQ(store.Sha256(), "");
  const std::string text = ValidCalibrationText();
  const std::string sha = store.Put(text, "upload");
  protocol::Sha256 expected;
  expected.Update(text);
  EXPECT_EQ(sha, expected.HexDigest());
  EXPECT_EQ(ReadFile(path), text);
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
  CalibrationStore reopened(path);
  EXPECT_EQ(reopened.Get(), text);
  EXPECT_EQ(reopened.Sha256(), sha);
}

TEST_F(CalibrationStoreTest, InvalidUploadNamesTheKeyAndKeepsTheOldFile) {
  const fs::path path = dir_ / "calibration.json";
  CalibrationStore store(path);
  const std::string text = ValidCalibrationText();
  store.Put(text, "upload");
  auto bad = nlohmann::json::parse(text);
  bad["mirrors"].erase(1);
  try {
    store.Put(bad.dump(), "upload");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("upload: mirrors: ", 0), 0u) << e.what();
  }
  EXPECT_THROW(store.Put("{not json", "upload"), ConfigError);
  EXPECT_THROW(store.Put("[]", "upload"), ConfigError);
  EXPECT_EQ(ReadFile(path), text);
  EXPECT_EQ(store.Get(), text);
}

// A stored file that no longer validates does not stop the device: it is set aside
// (kept for a person to look at), the device is uncalibrated and takes a new upload.
TEST_F(CalibrationStoreTest, InvalidStoredFileIsSetAsideAndANewOneCanBeUploaded) {
  const fs::path path = dir_ / "calibration.json";
  const std::string damaged = ValidCalibrationText().substr(0, 500);
  std::ofstream(path) << damaged;
  CalibrationStore store(path);
  EXPECT_FALSE(store.Get().has_value());
  EXPECT_EQ(store.Sha256(), "");
  EXPECT_EQ(store.problem().rfind(path.string() + ": ", 0), 0u) << store.problem();
  EXPECT_NE(store.problem().find("(set aside as calibration.json.invalid)"), std::string::npos)
      << store.problem();
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(ReadFile(path.string() + ".invalid"), damaged);
  const std::string text = ValidCalibrationText();
  store.Put(text, "upload");
  EXPECT_EQ(store.problem(), "");
  EXPECT_EQ(CalibrationStore(path).Get(), text);
}

}  // namespace
}  // namespace mirrorscan::service

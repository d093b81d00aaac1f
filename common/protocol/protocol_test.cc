#include "common/protocol/protocol.h"

#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>

#include "common/protocol/sha256.h"

namespace mirrorscan::protocol {
namespace {

TEST(ScanIdTest, AcceptsOnlyTheStoreFormat) {
  EXPECT_TRUE(IsValidScanId("20261124T035501Z-0001"));
  for (const char* bad :
       {"", "..", "../20261124T035501Z-0001", "20261124T035501Z-000", "20261124T035501Z-00011",
        "20261124X035501Z-0001", "20261124T035501Z_0001", "2026112aT035501Z-0001",
        "20261124T035501Z-0/01", "20261124T035501Z-%2f1"}) {
    EXPECT_FALSE(IsValidScanId(bad)) << bad;
  }
}

TEST(ProtocolJsonTest, StatusRoundTrips) {
  DeviceStatus status;
  status.board = "virtual";
  status.firmware_version = "0.1.0";
  status.calibration_sha256 = std::string(64, 'a');
  status.calibration_problem = "calibration.json: lasers: missing";
  status.scan.state = "sweeping";
  status.scan.scan_id = "20261124T035501Z-0001";
  status.scan.progress = 0.25;
  status.scan.frames = 12;
  status.disk.free_bytes = 1234;
  const nlohmann::json j = status;
  EXPECT_EQ(j.at("api_version"), kApiVersion);
  const auto back = j.get<DeviceStatus>();
  EXPECT_EQ(back.board, "virtual");
  EXPECT_EQ(back.calibration_problem, status.calibration_problem);
  EXPECT_EQ(back.scan.state, "sweeping");
  EXPECT_EQ(back.scan.scan_id, status.scan.scan_id);
  EXPECT_DOUBLE_EQ(back.scan.progress, 0.25);
  EXPECT_EQ(back.scan.frames, 12u);
  EXPECT_EQ(back.disk.free_bytes, 1234u);
}

TEST(ProtocolJsonTest, ErrorsCarryCodeAndMessage) {
  const nlohmann::json j = ApiError{std::string(ErrorCode(404)), "no scan 20261124T035501Z-0001"};
  EXPECT_EQ(j.at("error"), "not_found");
  EXPECT_EQ(j.get<ApiError>().message, "no scan 20261124T035501Z-0001");
  EXPECT_EQ(ErrorCode(401), "unauthorized");
  EXPECT_EQ(ErrorCode(416), "range_not_satisfiable");
}

TEST(ProtocolJsonTest, MissingRequiredFieldThrows) {
  EXPECT_THROW(nlohmann::json::object().get<ScanSummary>(), nlohmann::json::exception);
}

TEST(Sha256Test, KnownVectors) {
  Sha256 empty;
  EXPECT_EQ(empty.HexDigest(), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  Sha256 abc;
  abc.Update(std::string_view("a"));
  abc.Update(std::string_view("bc"));
  EXPECT_EQ(abc.HexDigest(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_THROW(abc.Update(std::string_view("x")), std::logic_error);
}

TEST(Sha256Test, FileMatchesInMemoryDigest) {
  const auto path = std::filesystem::path(testing::TempDir()) /
                    ("sha256_test_" + std::to_string(::getpid()) + ".bin");
  std::string bytes(200000, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 7919 % 251);
  std::ofstream(path, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  Sha256 sha;
  sha.Update(bytes);
  EXPECT_EQ(Sha256::HexOfFile(path), sha.HexDigest());
  EXPECT_THROW(Sha256::HexOfFile(path.string() + ".missing"), std::runtime_error);
}

TEST(SecretsEqualTest, ComparesContentAndLength) {
  EXPECT_TRUE(SecretsEqual("s3cret-token", "s3cret-token"));
  EXPECT_FALSE(SecretsEqual("s3cret-token", "s3cret-tokem"));
  EXPECT_FALSE(SecretsEqual("s3cret-token", "s3cret-token-"));
  EXPECT_FALSE(SecretsEqual("", "x"));
}

}  // namespace
}  // namespace mirrorscan::protocol

#include "firmware/service/token.h"

#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;

class TokenFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(testing::TempDir()) /
           ("token_test_" + std::to_string(::getpid()) + "_" +
            std::string(testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(TokenFileTest, GeneratedOnceWithMode0600ThenReread) {
  const fs::path file = dir_ / "state" / "token";
  const std::string token = LoadOrCreateTokenFile(file);
  EXPECT_EQ(token.size(), 64u);
  EXPECT_TRUE(board::IsValidServiceToken(token));
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(LoadOrCreateTokenFile(file), token);
  // A second device (another directory) gets a different token.
  EXPECT_NE(LoadOrCreateTokenFile(dir_ / "other" / "token"), token);
}

TEST_F(TokenFileTest, RefusesAFileOthersCanRead) {
  const fs::path file = dir_ / "token";
  LoadOrCreateTokenFile(file);
  ::chmod(file.c_str(), 0644);
  try {
    LoadOrCreateTokenFile(file);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("mode 0644"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}

TEST_F(TokenFileTest, RefusesAMalformedToken) {
  fs::create_directories(dir_);
  const fs::path file = dir_ / "token";
  std::ofstream(file) << "short\n";
  ::chmod(file.c_str(), 0600);
  EXPECT_THROW(LoadOrCreateTokenFile(file), std::runtime_error);
}

TEST(ResolveServiceTokenTest, FixedTokenWins) {
  board::ServiceConfig service;
  service.token = "virtual-dev-token-not-a-secret";
  EXPECT_EQ(ResolveServiceToken(service), "virtual-dev-token-not-a-secret");
}

}  // namespace
}  // namespace mirrorscan::service

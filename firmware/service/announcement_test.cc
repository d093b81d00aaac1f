// Each hardware board's Avahi service file announces the port its board.json listens on,
// under the service type the host's `mirrorscan device discover` browses for.
#include <fstream>
#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include "common/protocol/protocol.h"
#include "firmware/board/board_config.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;

TEST(AnnouncementTest, AvahiServiceFilesMatchTheBoards) {
  int checked = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(MIRRORSCAN_SOURCE_DIR) / "boards")) {
    const fs::path file = entry.path() / "mirrorscan.avahi.service";
    if (!fs::exists(file)) continue;
    SCOPED_TRACE(file.string());
    std::ifstream in(file);
    std::stringstream text;
    text << in.rdbuf();
    const std::string xml = text.str();
    const board::BoardConfig board = board::BoardConfig::Load(entry.path() / "board.json");
    const std::string port = board.service.listen.substr(board.service.listen.rfind(':') + 1);
    std::smatch match;
    ASSERT_TRUE(std::regex_search(xml, match, std::regex("<port>([0-9]+)</port>")));
    EXPECT_EQ(match[1].str(), port);
    EXPECT_NE(xml.find("<type>" + std::string(protocol::kServiceType) + "</type>"),
              std::string::npos);
    EXPECT_NE(xml.find("<txt-record>board=" + board.board + "</txt-record>"), std::string::npos);
    ++checked;
  }
  EXPECT_EQ(checked, 2);  // rpi4, rpi5; the virtual board is not announced
}

}  // namespace
}  // namespace mirrorscan::service

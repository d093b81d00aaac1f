#include "tests/support/virtual_board.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/hal/replay/replay_camera.h"

namespace mirrorscan::test_support {

namespace fs = std::filesystem;

fs::path WriteVirtualBoard(const fs::path& dir, double sweep_end_mm, bool replay) {
  const fs::path source = MIRRORSCAN_SOURCE_DIR;
  nlohmann::json board;
  std::ifstream(source / "boards" / "virtual" / "board.json") >> board;
  board["scan"]["sweep_start_mm"] = 200;
  board["scan"]["sweep_end_mm"] = sweep_end_mm;
  board["virtual"]["scene"] =
      (source / "boards" / "virtual" / "scenes" / "mannequin.json").string();
  if (replay) {
    for (int c = 0; c < 2; ++c) {
      const fs::path frames = dir / ("frames" + std::to_string(c));
      fs::create_directories(frames);
      std::vector<uint8_t> pixels(160 * 120);
      for (int v = 0; v < 120; ++v) {
        const double d = (v - 60.0) / 1.2;
        std::fill_n(pixels.begin() + v * 160, 160,
                    static_cast<uint8_t>(20 + 180 * std::exp(-0.5 * d * d)));
      }
      hal::WritePgm(frames / "0.pgm", 160, 120, pixels.data());
      auto& camera = board["cameras"][c];
      camera.erase("id");
      camera["backend"] = "replay";
      camera["path"] = frames.string();
      camera["width"] = 160;
      camera["height"] = 120;
    }
  }
  const fs::path file = dir / "board.json";
  std::ofstream(file) << board.dump(2);
  return file;
}

}  // namespace mirrorscan::test_support

#include "host/cli/calibrate_intrinsics_command.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "host/calibration/intrinsics.h"

namespace mirrorscan::cli {

namespace fs = std::filesystem;

namespace {

struct IntrinsicsOptions {
  std::vector<std::string> images;
  std::string chessboard;
  std::string charuco;
  double square_mm = 0.0;
  double marker_mm = 0.0;
  std::string dictionary = "DICT_4X4_50";
  std::string out;
  bool json = false;
};

CalibrationPattern PatternFrom(const IntrinsicsOptions& o) {
  if (o.chessboard.empty() == o.charuco.empty())
    throw IntrinsicsError("give exactly one of --chessboard COLSxROWS or --charuco COLSxROWS");
  CalibrationPattern pattern;
  if (!o.chessboard.empty()) {
    std::tie(pattern.columns, pattern.rows) =
        CalibrationPattern::ParseSize(o.chessboard, "--chessboard");
  } else {
    pattern.kind = CalibrationPattern::Kind::kCharuco;
    std::tie(pattern.columns, pattern.rows) = CalibrationPattern::ParseSize(o.charuco, "--charuco");
    pattern.marker_mm = o.marker_mm;
    pattern.dictionary = o.dictionary;
  }
  pattern.square_mm = o.square_mm;
  pattern.Validate();
  return pattern;
}

void Run(const IntrinsicsOptions& o) {
  const CalibrationPattern pattern = PatternFrom(o);
  const std::vector<fs::path> images(o.images.begin(), o.images.end());
  const IntrinsicsResult result =
      CalibrateIntrinsics(images, pattern, [](size_t done, size_t total, const std::string& image) {
        std::fprintf(stderr, "calibrate-intrinsics: [%zu/%zu] %s\n", done, total, image.c_str());
      });
  const nlohmann::json json = IntrinsicsToJson(result);
  const std::string text = json.dump(2) + "\n";
  {
    std::ofstream out(o.out, std::ios::trunc);
    out << text;
    if (!out.flush()) throw std::runtime_error("--out " + o.out + ": cannot write");
  }
  if (o.json) {
    std::fputs(text.c_str(), stdout);
  } else {
    const CameraIntrinsics& k = result.intrinsics;
    std::printf(
        "%zu images, %dx%d: fx %.2f fy %.2f cx %.2f cy %.2f px, k1 %.5f k2 %.5f p1 %.6f "
        "p2 %.6f k3 %.5f, RMS %.3f px\nwrote %s\n",
        result.views.size(), k.width, k.height, k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2,
        k.k3, result.rms_px, o.out.c_str());
  }
}

}  // namespace

void AddCalibrateIntrinsicsCommand(CLI::App& app) {
  auto options = std::make_shared<IntrinsicsOptions>();
  auto* cmd = app.add_subcommand(
      "calibrate-intrinsics",
      "Calibrate a lens (K and k1, k2, p1, p2, k3) from photographs of a chessboard or "
      "ChArUco board");
  cmd->add_option("IMAGE", options->images, "Photographs of the board (every one must show it)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--chessboard", options->chessboard,
                  "Chessboard by inner corners, COLSxROWS (OpenCV's sample board is 9x6)");
  cmd->add_option("--charuco", options->charuco, "ChArUco board by squares, COLSxROWS");
  cmd->add_option("--square", options->square_mm, "Square size, mm")->required();
  cmd->add_option("--marker", options->marker_mm, "ChArUco marker size, mm");
  cmd->add_option("--dictionary", options->dictionary, "ChArUco marker dictionary")
      ->capture_default_str();
  cmd->add_option("--out", options->out, "Write intrinsics.json here")->required();
  cmd->add_flag("--json", options->json, "Print the written JSON");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

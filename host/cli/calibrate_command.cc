#include "host/cli/calibrate_command.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/config/calibration.h"
#include "host/board/board_json.h"
#include "host/calibration/calibrate.h"
#include "host/calibration/intrinsics.h"

namespace mirrorscan::cli {

namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  std::vector<std::string> images;
  std::vector<std::string> intrinsics;  // CAMERA=intrinsics.json
  std::string board;
  std::string out;
  std::string verify;
  std::string report;
  bool json = false;
};

// Written beside, then renamed over, so a crash never leaves half a file.
void WriteAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".partial";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << text;
    if (!out.flush()) throw std::runtime_error("cannot write " + temporary.string());
  }
  fs::rename(temporary, path);
}

std::vector<calibration::CameraImage> ReadImages(const CalibrateOptions& o,
                                                 const calibration::CalibrationSettings& s) {
  std::vector<calibration::CameraImage> images;
  for (const std::string& argument : o.images) {
    const size_t equals = argument.find('=');
    std::string name, path = argument;
    if (equals != std::string::npos) {
      name = argument.substr(0, equals);
      path = argument.substr(equals + 1);
    } else if (o.images.size() == 1 && !s.camera_names.empty()) {
      name = s.camera_names.front();
    } else {
      throw std::runtime_error("--image " + argument +
                               ": with several images, name each camera (--image upper=U.png)");
    }
    if (!fs::is_regular_file(path)) throw std::runtime_error("--image " + path + ": no such file");
    const cv::Mat gray = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (gray.empty()) throw std::runtime_error("--image " + path + ": cannot read the image");
    for (const auto& image : images) {
      if (image.name == name) throw std::runtime_error("--image: camera " + name + " given twice");
    }
    images.push_back({name, gray, std::nullopt, {}});
  }
  for (const std::string& argument : o.intrinsics) {
    const size_t equals = argument.find('=');
    std::string name, path = argument;
    if (equals != std::string::npos) {
      name = argument.substr(0, equals);
      path = argument.substr(equals + 1);
    } else if (images.size() == 1) {
      name = images.front().name;
    } else {
      throw std::runtime_error("--intrinsics " + argument +
                               ": with several cameras, name each (--intrinsics upper=I.json)");
    }
    auto image = std::find_if(images.begin(), images.end(),
                              [&](const calibration::CameraImage& i) { return i.name == name; });
    if (image == images.end()) {
      throw std::runtime_error("--intrinsics " + argument + ": no --image for camera " + name);
    }
    if (image->lens) throw std::runtime_error("--intrinsics: camera " + name + " given twice");
    const LensCalibration lens = ReadLensJson(path);
    image->lens = lens.intrinsics;
    image->lens_support_px = lens.support_px;
  }
  return images;
}

void Run(const CalibrateOptions& o) {
  const calibration::CalibrationSettings settings =
      host_board::CalibrationSettingsFromBoard(o.board);
  const std::vector<calibration::CameraImage> images = ReadImages(o, settings);
  calibration::CalibrationResult result;
  if (!o.verify.empty()) {
    result = calibration::Verify(images, settings, Calibration::Load(o.verify));
  } else {
    if (o.out.empty()) throw std::runtime_error("--out is required (or --verify CALIBRATION)");
    result = calibration::Calibrate(images, settings);
  }
  if (!o.report.empty()) {
    WriteAtomically(o.report + ".json", result.ReportJson().dump(2) + "\n");
    for (size_t c = 0; c < images.size(); ++c) {
      const std::string png = o.report + "-" + images[c].name + ".png";
      if (!cv::imwrite(png, calibration::DrawReport(images[c], result.cameras[c]))) {
        throw std::runtime_error("--report: cannot write " + png);
      }
    }
  }
  if (result.ok && o.verify.empty()) {
    WriteAtomically(o.out, result.calibration->ToJson().dump(2) + "\n");
  }
  if (o.json) {
    std::printf("%s\n", result.ReportJson().dump(2).c_str());
  } else {
    for (const auto& camera : result.cameras) {
      if (o.verify.empty()) {
        std::printf("%-6s lens   %s, data on %.0f%% of the image\n", camera.name.c_str(),
                    camera.coverage.lens_fixed ? "from calibrate-intrinsics" : "from the target",
                    100.0 * camera.coverage.fraction);
      }
      for (const auto& v : camera.views) {
        std::printf("%-6s %-6s %2zu markers  RMS %s%.3f px  max %.3f px\n", camera.name.c_str(),
                    calibration::ViewName(v.view), v.found.size(),
                    o.verify.empty() ? "" : "vs stored ", v.rms_after_px, v.max_after_px);
      }
    }
    if (result.ok && result.calibration) {
      for (const auto& m : result.calibration->mirrors) {
        std::printf("mirror %-5s normal (%.5f, %.5f, %.5f) offset %.3f mm\n", m.name.c_str(),
                    m.plane.normal.x(), m.plane.normal.y(), m.plane.normal.z(), m.plane.offset);
      }
      std::printf(o.verify.empty() ? "calibration written to %s\n" : "%s still holds\n",
                  o.verify.empty() ? o.out.c_str() : o.verify.c_str());
    }
  }
  if (!result.ok) {
    for (const auto& f : result.failures) std::fprintf(stderr, "  - %s\n", f.c_str());
    throw std::runtime_error(o.verify.empty()
                                 ? "calibration failed (see above); " + o.out + " not written"
                                 : "verification failed (see above)");
  }
}

}  // namespace

void AddCalibrateCommand(CLI::App& app) {
  auto options = std::make_shared<CalibrateOptions>();
  auto* command = app.add_subcommand(
      "calibrate", "Calibrate camera(s) and mirrors from one image of the three-panel target");
  command
      ->add_option("--image", options->images,
                   "Target image, one per camera: CAMERA=PATH (a single PATH means the board's "
                   "first camera)")
      ->required();
  command
      ->add_option("--intrinsics", options->intrinsics,
                   "The lens of a camera from calibrate-intrinsics, held fixed: CAMERA=FILE")
      ->check([](const std::string& argument) {
        const std::string path = argument.substr(argument.find('=') + 1);
        return std::filesystem::is_regular_file(path) ? std::string() : "no such file: " + path;
      });
  command->add_option("--board", options->board, "board.json (cameras, calibration limits)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--out", options->out, "calibration.json to write (only when it passes)");
  command
      ->add_option("--verify", options->verify,
                   "Check this calibration.json against the images instead of calibrating")
      ->check(CLI::ExistingFile);
  command->add_option("--report", options->report,
                      "Write PREFIX.json (checks, residuals, markers) and PREFIX-CAMERA.png");
  command->add_flag("--json", options->json, "Print the report as JSON");
  command->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

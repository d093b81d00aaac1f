#include "host/cli/peaks_command.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/peaks/peaks.h"
#include "host/board/board_json.h"

namespace mirrorscan::cli {

namespace fs = std::filesystem;

namespace {

struct PeaksOptions {
  std::vector<std::string> images;
  std::string board;
  std::string estimator;
  int threshold = -1;
  bool csv = false;
  bool json = false;
  int bench = 0;
  std::string overlay;
};

PeakParams LoadParams(const PeaksOptions& o) {
  PeakParams params = o.board.empty() ? PeakParams() : host_board::PeakParamsFromBoard(o.board);
  if (!o.estimator.empty()) {
    bool found = false;
    std::string names;
    for (PeakEstimator e : AllPeakEstimators()) {
      names += (names.empty() ? "" : ", ") + std::string(ToString(e));
      if (o.estimator == ToString(e)) {
        params.estimator = e;
        found = true;
      }
    }
    if (!found) throw std::runtime_error("--estimator " + o.estimator + ": not one of " + names);
  }
  if (o.threshold >= 0) params.threshold_dn = o.threshold;
  params.Validate();
  return params;
}

cv::Mat Decode(const std::string& path) {
  cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty())
    throw std::runtime_error(path + ": cannot read the image (PNG or PGM expected)");
  if (image.depth() != CV_8U) throw std::runtime_error(path + ": expected an 8-bit image");
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
  return image;
}

ImageView View(const cv::Mat& image) {
  return ImageView{image.data, image.cols, image.rows, static_cast<ptrdiff_t>(image.step[0])};
}

// Detections drawn on the frame (dimmed, enlarged 3×, so the marks stand out from the
// stripes and sub-pixel rows can be seen): one short tick per peak, coloured by score
// from red (weak) to green (strong).
void WriteOverlay(const std::string& path, const cv::Mat& image, const std::vector<Peak>& peaks) {
  constexpr int kScale = 3;
  cv::Mat gray, color;
  cv::resize(image, gray, cv::Size(), kScale, kScale, cv::INTER_NEAREST);
  gray.convertTo(gray, CV_8U, 0.4);
  cv::cvtColor(gray, color, cv::COLOR_GRAY2BGR);
  for (const Peak& p : peaks) {
    const int y = static_cast<int>(std::lround((p.v + 0.5) * kScale - 0.5));
    if (y < 0 || y >= color.rows) continue;
    const double s = std::clamp(static_cast<double>(p.score), 0.0, 1.0);
    const cv::Vec3b mark(0, static_cast<uint8_t>(255 * s), static_cast<uint8_t>(255 * (1 - s)));
    for (int x = p.u * kScale; x < (p.u + 1) * kScale; ++x) color.at<cv::Vec3b>(y, x) = mark;
  }
  if (!cv::imwrite(path, color)) throw std::runtime_error("--overlay: cannot write " + path);
}

void Run(const PeaksOptions& o) {
  const PeakParams params = LoadParams(o);
  std::vector<cv::Mat> images;
  for (const auto& path : o.images) images.push_back(Decode(path));

  PeakExtractor extractor;
  std::vector<Peak> peaks;
  nlohmann::json results = nlohmann::json::array();
  if (o.csv) std::printf("image,u,v,intensity,width,score\n");
  for (size_t i = 0; i < images.size(); ++i) {
    ExtractPeaks(View(images[i]), params, &extractor, &peaks);
    if (o.csv) {
      for (const Peak& p : peaks) {
        std::printf("%s,%u,%.4f,%.1f,%.3f,%.3f\n", o.images[i].c_str(), p.u, p.v, p.intensity,
                    p.width, p.score);
      }
    } else if (o.json) {
      nlohmann::json list = nlohmann::json::array();
      for (const Peak& p : peaks) list.push_back({p.u, p.v, p.intensity, p.width, p.score});
      results.push_back(
          {{"image", o.images[i]}, {"peaks", peaks.size()}, {"u_v_intensity_width_score", list}});
    } else {
      std::printf("%s: %zu peaks\n", o.images[i].c_str(), peaks.size());
    }
    if (!o.overlay.empty()) {
      std::string out = o.overlay;
      if (images.size() > 1) {
        const fs::path p(o.overlay);
        out = (p.parent_path() /
               (p.stem().string() + "_" + std::to_string(i) + p.extension().string()))
                  .string();
      }
      WriteOverlay(out, images[i], peaks);
    }
  }

  if (o.bench > 0) {
    // Decoding excluded: extraction only, over the decoded frames, N times.
    size_t frames = 0, bytes = 0, total_peaks = 0;
    const auto start = std::chrono::steady_clock::now();
    for (int n = 0; n < o.bench; ++n) {
      for (const cv::Mat& image : images) {
        ExtractPeaks(View(image), params, &extractor, &peaks);
        ++frames;
        bytes += image.total();
        total_peaks += peaks.size();
      }
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const nlohmann::json bench = {{"frames", frames},
                                  {"seconds", seconds},
                                  {"frames_per_second", frames / seconds},
                                  {"megabytes_per_second", bytes / seconds / 1e6},
                                  {"peaks_per_frame", static_cast<double>(total_peaks) / frames},
                                  {"simd_target", PeakExtractor::SimdTarget()}};
    if (o.json) {
      results.push_back({{"bench", bench}});
    } else {
      std::fprintf(o.csv ? stderr : stdout,
                   "bench: %zu frames in %.3f s: %.0f frames/s, %.0f MB/s (%s)\n", frames, seconds,
                   frames / seconds, bytes / seconds / 1e6, PeakExtractor::SimdTarget().c_str());
    }
  }
  if (o.json) std::printf("%s\n", results.dump(2).c_str());
}

}  // namespace

void AddPeaksCommand(CLI::App& app) {
  auto options = std::make_shared<PeaksOptions>();
  auto* cmd =
      app.add_subcommand("peaks", "Run the on-device laser peak extractor on PNG/PGM frames");
  cmd->add_option("IMAGE", options->images, "Frames (8-bit PNG or PGM)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--board", options->board,
                  "Take the extractor parameters from this board.json's \"peaks\"")
      ->check(CLI::ExistingFile);
  cmd->add_option("--estimator", options->estimator, "Sub-pixel estimator (overrides the board)");
  cmd->add_option("--threshold", options->threshold, "Minimum peak above local background, DN")
      ->check(CLI::Range(0, 255));
  cmd->add_flag("--csv", options->csv,
                "CSV: image,u,v,intensity,width,score (v sub-pixel, pixel centres integer)");
  cmd->add_flag("--json", options->json, "Machine-readable output");
  cmd->add_option("--bench", options->bench,
                  "Run extraction N times over the decoded frames; print frames/s and MB/s")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--overlay", options->overlay, "Write the frame with detections drawn (PNG, 3x)");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

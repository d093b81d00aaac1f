#include "boards/virtual/sweep_peaks.h"

#include <cmath>
#include <utility>

namespace mirrorscan::virtual_cabinet {

FrameRecord SweepFrameRecord(const Scene& scene, int camera, int frame, const GrayImage& image,
                             bool lasers_on, const PeakParams& params, PeakExtractor* extractor) {
  const double t = scene.FrameTime(frame);
  FrameRecord record;
  record.camera = static_cast<uint8_t>(camera);
  record.lasers_on = lasers_on;
  record.sequence = static_cast<uint32_t>(frame);
  record.timestamp_ns = static_cast<int64_t>(std::llround(t * 1e9));
  record.slide_position_mm = scene.lasers.HeightAt(0, t);
  ExtractPeaks(ImageView{image.pixels.data(), image.width, image.height, image.width}, params,
               extractor, &record.peaks);
  return record;
}

std::vector<FrameRecord> RenderSweepPeaks(
    const Scene& scene, const Renderer& renderer, const SweepPeaksOptions& options,
    const std::function<void(const FrameRecord& record, double t)>& on_frame) {
  const int end_frame = options.end_frame < 0 ? scene.frames : options.end_frame;
  const int cameras =
      options.cameras < 0 ? static_cast<int>(scene.cameras.size()) : options.cameras;
  PeakExtractor extractor;
  std::vector<FrameRecord> records;
  for (int frame = options.first_frame; frame < end_frame; frame += options.frame_step) {
    const double t = scene.FrameTime(frame);
    for (int camera = 0; camera < cameras; ++camera) {
      const GrayImage image = renderer.RenderFrame(camera, t, static_cast<uint64_t>(frame));
      FrameRecord record = SweepFrameRecord(scene, camera, frame, image, /*lasers_on=*/true,
                                            options.peak_params, &extractor);
      if (on_frame) on_frame(record, t);
      records.push_back(std::move(record));
    }
  }
  return records;
}

nlohmann::json SweepArchiveHeader(const Scene& scene) {
  nlohmann::json cameras = nlohmann::json::array();
  for (const auto& c : scene.cameras) {
    cameras.push_back({{"name", c.name},
                       {"width", c.camera.intrinsics.width},
                       {"height", c.camera.intrinsics.height},
                       {"fps", c.fps}});
  }
  return {{"cameras", cameras},
          {"lasers", {{"count", scene.lasers.count}, {"spacing_mm", scene.lasers.spacing_mm}}},
          {"slide", {{"speed_mm_s", scene.lasers.speed_mm_s}}},
          {"start_steady_ns", 0},
          {"calibration", scene.TrueCalibration()}};
}

}  // namespace mirrorscan::virtual_cabinet

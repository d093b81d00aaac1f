#pragma once
// A sweep of the virtual cabinet reduced to what the board stores: each rendered frame's
// laser peaks (the on-device extractor) in a FrameRecord, and the archive header a device
// writes before them. The tests, the reconstruction benchmark and `mirrorscan sim scan` make
// their archives this one way.
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "common/peaks/peaks.h"
#include "common/scan_format/scan_format.h"

namespace mirrorscan::virtual_cabinet {

// The record of one rendered frame: its peaks, the frame's time and the virtual drive's
// position readback (laser 0's height, exact).
FrameRecord SweepFrameRecord(const Scene& scene, int camera, int frame, const GrayImage& image,
                             bool lasers_on, const PeakParams& params, PeakExtractor* extractor);

struct SweepPeaksOptions {
  int first_frame = 0;
  int end_frame = -1;  // one past the last; -1: the scene's frames
  int frame_step = 1;
  int cameras = -1;  // the scene's first this many cameras; -1: all
  PeakParams peak_params;
};

// Renders the frames in order, every camera of a frame before the next frame, on this
// thread. `on_frame`, if given, sees each record with its frame's time as it is made.
std::vector<FrameRecord> RenderSweepPeaks(
    const Scene& scene, const Renderer& renderer, const SweepPeaksOptions& options = {},
    const std::function<void(const FrameRecord& record, double t)>& on_frame = {});

// The header a device writes for this scene's sweep (docs/scan-format.md): the cameras, the
// lasers, the slide's speed, frame time 0 as the sweep's t = 0, and the scene's true
// calibration embedded (a caller that scans with another one replaces it).
nlohmann::json SweepArchiveHeader(const Scene& scene);

}  // namespace mirrorscan::virtual_cabinet

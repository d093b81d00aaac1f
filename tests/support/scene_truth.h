#pragma once

// Stored peaks against the virtual cabinet's truth for the slide position the frame
// records: what a scan of the virtual board must have found, whatever made it.
#include <vector>

#include "boards/virtual/renderer.h"
#include "common/scan_format/scan_format.h"
#include "tests/support/peak_truth.h"

namespace mirrorscan::test_support {

// The frame's peaks against the stripes the scene's lasers make with the slide at the
// frame's readback. The virtual cabinet puts laser k at start + (slide - sweep_start) +
// k·spacing (the sweep starts where the scene's time 0 is). The readback lags the slide
// by up to a poll period (~1.5 mm at 150 mm/s: ~1 px on the stripes), hence the
// tolerance.
inline PeakMatch MatchFrameToScene(const virtual_cabinet::Renderer& renderer,
                                   const FrameRecord& frame, double sweep_start_mm,
                                   double tolerance_px) {
  const double t = (frame.slide_position_mm - sweep_start_mm) / renderer.scene().lasers.speed_mm_s;
  std::vector<TruthRow> truth;
  for (const auto& p : renderer.Truth(frame.camera, t))
    truth.push_back({static_cast<int>(frame.sequence), p.u, p.v, p.laser});
  return MatchPeaks(frame.peaks, truth, tolerance_px);
}

}  // namespace mirrorscan::test_support

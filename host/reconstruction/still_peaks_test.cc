#include "host/reconstruction/still_peaks.h"

#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {
namespace {

// Two cameras, 40 frames each, lasers on. In camera 0: an ambient edge at row 200.3 in
// columns 100-139 in every frame (its row jittered by 0.15 px of noise), a laser line
// moving 2.5 px a frame, and a slow one moving 1 px a frame (a surface the camera sees
// nearly along the slide's travel). Camera 1 holds a line at camera 0's edge's row in every
// frame but at another place each frame: only a camera's own frames count.
TEST(StillPeaks, TheAmbientEdgeIsStillTheLaserLinesMove) {
  ScanArchive archive;
  std::mt19937 rng(3);
  std::normal_distribution<float> jitter(0.0f, 0.15f);
  constexpr int kFrames = 40;
  for (int f = 0; f < kFrames; ++f) {
    for (uint8_t camera = 0; camera < 2; ++camera) {
      FrameRecord frame;
      frame.camera = camera;
      frame.lasers_on = true;
      frame.sequence = static_cast<uint32_t>(f);
      frame.timestamp_ns = static_cast<int64_t>(f) * 33'333'333;
      for (uint16_t u = 100; u < 140; ++u) {
        Peak edge, fast, slow;
        edge.u = fast.u = slow.u = u;
        edge.v = camera == 0 ? 200.3f + jitter(rng) : 200.3f + 7.0f * static_cast<float>(f % 5);
        fast.v = 300.0f + 2.5f * static_cast<float>(f);
        slow.v = 500.0f + 1.0f * static_cast<float>(f);
        frame.peaks.push_back(edge);
        frame.peaks.push_back(fast);
        frame.peaks.push_back(slow);
      }
      archive.frames.push_back(frame);
    }
  }
  ReconstructSummary summary;
  PeakTable table = ReadPeaks(archive, 2, &summary);
  const size_t marked = MarkStillPeaks(2, &table);
  size_t edge = 0, edge_still = 0, moving_still = 0, other_camera_still = 0;
  for (const PeakState& p : table.peaks) {
    const bool camera0 = archive.frames[p.frame].camera == 0;
    const bool on_edge = p.v < 250;
    if (camera0 && on_edge) {
      ++edge;
      edge_still += p.still;
    } else if (!camera0 && on_edge) {
      other_camera_still += p.still;
    } else {
      moving_still += p.still;
    }
  }
  std::printf("%zu marked: the edge %zu of %zu, moving lines %zu, camera 1's %zu\n", marked,
              edge_still, edge, moving_still, other_camera_still);
  EXPECT_EQ(edge_still, edge);
  EXPECT_EQ(moving_still, 0u);
  EXPECT_EQ(other_camera_still, 0u);
  EXPECT_EQ(marked, edge);
}

}  // namespace
}  // namespace mirrorscan::reconstruction

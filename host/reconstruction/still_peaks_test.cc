#include "host/reconstruction/still_peaks.h"

#include <cmath>
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

// One camera, 120 frames. A dim edge (12 DN) at row 150.2 found in a quarter of the frames
// at random; a bright line (200 DN) moving 3 px a frame that crosses the edge's row every 40
// frames, as three lasers cross one surface point; and a dim line (14 DN) moving 2 px a
// frame, like a dark surface lit at a grazing angle. The edge's peaks are still; the
// lines', the bright one's on the edge's row too, are not.
TEST(StillPeaks, AnEdgeFoundNowAndThenIsStillTheLinesCrossingItAreNot) {
  ScanArchive archive;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> chance(0.0f, 1.0f);
  constexpr int kFrames = 120;
  size_t edge = 0;
  for (int f = 0; f < kFrames; ++f) {
    FrameRecord frame;
    frame.lasers_on = true;
    frame.sequence = static_cast<uint32_t>(f);
    frame.timestamp_ns = static_cast<int64_t>(f) * 33'333'333;
    const bool edge_found = chance(rng) < 0.25f;
    for (uint16_t u = 100; u < 120; ++u) {
      Peak bright, dim;
      bright.u = dim.u = u;
      bright.v = 150.2f + 3.0f * static_cast<float>(f % 40 - 20);
      bright.intensity = 200;
      dim.v = 400.0f + 2.0f * static_cast<float>(f);
      dim.intensity = 14;
      frame.peaks.push_back(bright);
      frame.peaks.push_back(dim);
      // The bright line's own peak stands for the edge's where both are on the row.
      if (edge_found && f % 40 != 20) {
        Peak p;
        p.u = u;
        p.v = 150.2f;
        p.intensity = 12;
        frame.peaks.push_back(p);
        ++edge;
      }
    }
    archive.frames.push_back(frame);
  }
  ReconstructSummary summary;
  PeakTable table = ReadPeaks(archive, 2, &summary);
  const size_t marked = MarkStillPeaks(2, &table);
  size_t edge_still = 0, lines_still = 0, crossing = 0, crossing_still = 0;
  for (const PeakState& p : table.peaks) {
    if (p.intensity == 12) {
      edge_still += p.still;
    } else {
      lines_still += p.still;
      if (std::abs(p.v - 150.2f) < 0.01f) {
        ++crossing;
        crossing_still += p.still;
      }
    }
  }
  std::printf("%zu marked: the edge %zu of %zu, the lines %zu (on the edge's row %zu of %zu)\n",
              marked, edge_still, edge, lines_still, crossing_still, crossing);
  EXPECT_EQ(edge_still, edge);
  EXPECT_EQ(crossing, 3u * 20u);
  EXPECT_EQ(lines_still, 0u);
  EXPECT_EQ(marked, edge);
}

}  // namespace
}  // namespace mirrorscan::reconstruction

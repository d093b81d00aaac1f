#pragma once
// Peaks that stay put from frame to frame (docs/reconstruction.md, stage 1).
#include <cstddef>

#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// A laser line moves in the image every frame: the slide moves 5 mm a frame, so a line
// crosses a pixel row in about one frame. An edge or texture of the ambient-lit scene stays
// where it is, and near the extractor's threshold it can pass for a dim line (at 10 DN the
// upper camera took the lower edge of f02's bust, lit only by the room, for a stripe in
// every frame: 900 points up to 770 mm off the body). A peak with a peak of the same camera
// within kStillPx of its row in the same column in at least kStillFrames of the kStillReach
// frames before and after it is the scene's: it is marked `still` and gets no hypothesis.
// The slowest laser line moves about 1.3 px a frame (5 mm seen through a mirror from 3.7 m
// at f 1150 px), so kStillPx leaves it moving while an edge's sub-pixel jitter stays inside.
// Returns how many were marked.
constexpr float kStillPx = 0.75f;
constexpr int kStillReach = 4;
constexpr int kStillFrames = 3;
size_t MarkStillPeaks(int threads, PeakTable* table);

}  // namespace mirrorscan::reconstruction

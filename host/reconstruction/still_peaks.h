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
// frames before and after it is the scene's: it is marked `still` and gets no hypothesis,
// unless it is brighter than kRecurringBrightness times the median of those (a laser line
// crossing the edge's row).
// The slowest laser line moves about 1.3 px a frame (5 mm seen through a mirror from 3.7 m
// at f 1150 px), so kStillPx leaves it moving while an edge's sub-pixel jitter stays inside.
//
// An edge barely above the threshold is found only now and then, seldom in three frames of
// eight, yet at the same row all through the sweep (f02's bust edges at 10 DN: 3,900 peaks
// in 5–30 % of the frames, 653 of its 737 cloud points beyond 5 mm). A surface point is
// crossed once by each laser, in one or two frames each, so a row of a column holds a few
// separate visits; a peak whose row (within kStillPx) holds peaks in kRecurringVisits
// visits (runs of frames more than kVisitGapFrames apart) is marked too, unless it is
// brighter than kRecurringBrightness times the median of the peaks there (f02's lasers
// crossing its edges' rows: 170–250 DN against the edges' 12–21).
// Returns how many were marked.
constexpr float kStillPx = 0.75f;
constexpr int kStillReach = 4;
constexpr int kStillFrames = 3;
constexpr int kRecurringVisits = 10;
constexpr int kVisitGapFrames = 3;
constexpr float kRecurringBrightness = 2.0f;
size_t MarkStillPeaks(int threads, PeakTable* table);

}  // namespace mirrorscan::reconstruction

#pragma once
// The archive's peaks as the stages see them (docs/reconstruction.md): in frame order, each
// frame's by column and row, with an O(1) lookup of a frame's peaks in a column, each frame's
// next frame of its camera, and every peak's state as the rules decide it.
#include <cstdint>
#include <utility>
#include <vector>

#include "common/scan_format/scan_format.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// Which rule decided a peak's hypothesis so far (the cloud's DecidedBy, and none yet).
enum class Rule : uint8_t { kNone, kCylinder, kVolume, kColumnCount, kLabelVote, kStereo };

// One peak as the stages see it: where it is, its hypotheses (Hypotheses, hypotheses.h:
// [first_hypothesis, first_hypothesis + hypotheses)) and what the rules decided.
struct PeakState {
  uint32_t frame = 0;  // archive frame index
  uint16_t u = 0;
  float v = 0;
  float score = 0;
  float intensity = 0;  // DN above the local background
  uint32_t first_hypothesis = 0;
  uint8_t hypotheses = 0;
  uint8_t region = 0;   // the calibration view region: 0 centre, 1 left, 2 right
  bool panel = false;   // the laser fit took it as a panel's line (laser-height data)
  bool no_ray = false;  // undistortion failed
  bool still = false;   // stays put across frames: the ambient scene's (still_peaks.h)
  int16_t chosen = -1;  // index among its hypotheses; -1: undecided or dropped
  Rule rule = Rule::kNone;
};

// The archive's peaks in frame order, each frame's sorted by column then row.
struct PeakTable {
  std::vector<PeakState> peaks;
  std::vector<uint32_t> frame_first;  // per archive frame, and one past the end
  // Per archive frame: whether its peaks are used (lasers on, some peaks).
  std::vector<bool> used;
  // Per archive frame: the next frame of the same camera (or -1).
  std::vector<int32_t> next_frame;

  // Per archive frame and column u in [0, columns], the first peak at u or right of it.
  int columns = 1;
  std::vector<uint32_t> column_first;

  // The frame's peaks in column u: [first, last).
  std::pair<uint32_t, uint32_t> Column(uint32_t frame, int u) const {
    if (u < 0 || u >= columns) return {0, 0};
    const size_t at = static_cast<size_t>(frame) * (columns + 1) + u;
    return {column_first[at], column_first[at + 1]};
  }
};

// The frames with the lasers on and some peak, counted into the summary (frames, peaks).
// ReconstructError when there is no peak at all.
PeakTable ReadPeaks(const ScanArchive& archive, int threads, ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

#pragma once
// Free space (docs/reconstruction.md, stage 5; dropped.seen_through).
#include <vector>

#include "common/scan_format/scan_format.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/rays.h"

namespace mirrorscan::reconstruction {

// Free space: a point is only where the rays through it saw nothing behind it. At its own
// pixel the other lasers light the same first surface, so their path lengths must agree
// with its own; and where another camera, or a mirror's view, looks through the point and
// sees further, it is not there, unless some view sees it. Wrong lasers and views that the
// vote carried along a whole label (an arm in front of a mirror taken for the torso in it, a
// laser taken for the next one consistently over many frames) fail one or the other. Both
// judge every point against the same set, before any is dropped.
// Undecides (PeakState::chosen -1) the peaks so refuted, counting them in `dropped`.
void DropPointsSeenThrough(const Geometry& g, const ScanArchive& archive, const PeakTable& table,
                           const Hypotheses& hyp, const ReconstructOptions& options, int threads,
                           std::vector<PeakState>* peaks, size_t* dropped);

}  // namespace mirrorscan::reconstruction

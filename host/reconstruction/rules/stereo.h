#pragma once
// Stereo (docs/reconstruction.md, stage 2): a hypothesis is confirmed where another camera,
// at its frame nearest in time, has a hypothesis of the same laser at the same place (moved
// by the plane's travel between the two frames). A right hypothesis is the one surface
// point both cameras see lit; two wrong ones coincide only where their curves in a laser
// plane happen to cross.
#include <array>
#include <vector>

#include "common/geometry/plane.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// Marks the confirmed hypotheses (Hypothesis::confirmed) of every peak with two or more,
// within max_mm; `planes` by archive frame.
void ConfirmByStereo(const ScanArchive& archive, const PeakTable& table,
                     const std::vector<std::array<Plane, kMaxLasers>>& planes, double max_mm,
                     int threads, Hypotheses* hyp);

// A peak still undecided with exactly one confirmed hypothesis takes it (DecidedBy::kStereo).
void DecideByStereo(const Hypotheses& hyp, int threads, std::vector<PeakState>* peaks);

}  // namespace mirrorscan::reconstruction

#pragma once
// Column counting (docs/reconstruction.md, stage 3).
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// Column counting: in one column of one view region, as many peaks as lasers are the
// lasers top (highest) to bottom. In a mirror's region an arm in front of the glass can add
// its stripe to the mirror's, and the count then takes the arm's peak for the lowest laser
// in the mirror (the mannequin's two wrong column-count points, 17 mm off); counting in the
// centre region only fixed them but left the cuboid's stripes that run on into a mirror's
// region without the support the vote needs there (CuboidThroughTheTrueCalibration...: 5,700
// fewer points), so it counts in every region.
// Decides peaks the rules before left open (DecidedBy::kColumnCount); nothing with one laser.
void DecideByColumnCount(PeakTable* table, const Hypotheses& hyp, int laser_count, int threads);

}  // namespace mirrorscan::reconstruction

#pragma once
// The bounding cylinder's rules (docs/reconstruction.md, stage 2, "deciding alone"): a peak
// with one hypothesis takes it; a peak that stereo left open takes its one hypothesis inside
// the cylinder's core. Both are DecidedBy::kCylinder.
#include <vector>

#include "host/reconstruction/bounding_cylinder.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// Every peak with exactly one hypothesis takes it.
void DecideByOneHypothesis(int threads, std::vector<PeakState>* peaks);

// A peak still undecided takes the one hypothesis inside the cylinder's core among those
// another camera confirmed (or among all, none confirmed). The floor and the panels are
// surfaces too: such a hypothesis leaves the core no single answer. In a mirror's region
// the core decides nothing while both the direct ray and a mirror's view have a hypothesis
// of the subject.
void DecideByCore(const Hypotheses& hyp, const BoundingCylinder& cylinder, int threads,
                  std::vector<PeakState>* peaks);

}  // namespace mirrorscan::reconstruction

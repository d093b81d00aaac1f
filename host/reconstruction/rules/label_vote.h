#pragma once
// Labels and the vote (docs/reconstruction.md, stage 4): peaks that are neighbours in
// (column, frame) of one camera and share a hypothesis nearby are one label (union-find);
// each label's (view, laser) is the majority of its decided peaks, and it decides the
// label's undecided peaks that have it (DecidedBy::kLabelVote).
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// Peaks that disagree with their label's vote are undecided again (dropped.conflict), so are
// labels with no decided peak (dropped.ambiguous); in a mirror's region the vote gives the
// direct view only near a peak the rules before decided so (else dropped.unsupported).
void DecideByLabelVote(const Hypotheses& hyp, const ReconstructOptions& options, int threads,
                       PeakTable* table, ReconstructSummary* summary);

}  // namespace mirrorscan::reconstruction

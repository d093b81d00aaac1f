#pragma once
// The carved volume (docs/reconstruction.md, stage 3): the voxels of the points decided
// alone (and their 26 neighbours) are the subject's volume as the scan carves it; a peak
// with exactly one hypothesis there, which its ray reaches without passing a seen surface,
// takes it (DecidedBy::kVolume).
#include <vector>

#include "host/reconstruction/bounding_cylinder.h"
#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/peak_table.h"
#include "host/reconstruction/rays.h"

namespace mirrorscan::reconstruction {

// Decides the peaks the cylinder and stereo left open, by the volume of those they decided.
void DecideByVolume(std::vector<PeakState>* peaks, const Hypotheses& hyp,
                    const BoundingCylinder& cylinder, const Geometry& g, int threads);

}  // namespace mirrorscan::reconstruction

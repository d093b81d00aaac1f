#pragma once
// The laser sequence at a pixel (docs/reconstruction.md, stage 2): a pixel of a camera sees
// one surface point all sweep long, and every laser that passes that point's height lights
// it, at moments one laser spacing of slide travel apart (the emitters of every laser stand
// at the same place on the slide, so a point one laser reaches, every laser reaches). A
// hypothesis whose laser is wrong puts the point a spacing above or below the surface: the
// other lasers would have lit that place at moments when the pixel saw nothing.
#include <cstdint>

#include "host/reconstruction/hypotheses.h"
#include "host/reconstruction/laser_planes.h"
#include "host/reconstruction/peak_table.h"

namespace mirrorscan::reconstruction {

// For every hypothesis of a peak with two or more: where each other laser's plane passes the
// hypothesis' point during the sweep (the camera's frames either side of that moment), a peak
// of the same camera in the same column within 2 rows of this one's is looked for
// (Hypothesis::sequence_seen); the lasers whose moment lies in the sweep but show nothing
// there are counted in Hypothesis::sequence_missing.
void MarkLaserSequence(const PeakTable& table, const LaserPlanes& planes, int threads,
                       Hypotheses* hyp);

// Which of a peak's hypotheses the sequence allows (bit h for hypothesis h): of each view's,
// those that no other laser contradicts and that the most other lasers saw, when one of the
// view's has another laser's word and none against it; else all of the view's. The floor and
// the panels are always allowed (their lasers' sequence is not the subject's).
uint32_t SequenceAllows(const Hypothesis* first, int count);

// Whether the sequence speaks against hypothesis h outright, for the rules that decide from
// a stripe or a column rather than from the peak's own evidence (the count, the vote):
// other lasers would have lit its point and the pixel saw nothing, while another hypothesis
// of the peak has no such word against it and is of the same view or was seen by another
// laser (a hand seen directly, its lasers lit it at their moments, is no mirror's stripe).
bool SequenceRefutes(const Hypothesis* first, int count, int h);

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/hypotheses.h"

#include <cmath>
#include <limits>
#include <string>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::reconstruction {

namespace {

// How close to a laser plane a ray's panel hit must be to be that laser's line there: the
// panel's place is the calibration's estimate, the lasers are 200 mm apart.
constexpr double kPanelLineMm = 10.0;

// Every (view, laser) this peak could be, inside the bounding cylinder (or on the floor).
void HypothesizePeak(const Geometry& g, const FrameRecord& frame,
                     const std::array<Plane, kMaxLasers>& planes, int laser_count,
                     const BoundingCylinder& cylinder, double mirror_clearance_mm,
                     const std::optional<Ray3d>& ray, PeakState* peak, Hypotheses::Writer* out) {
  peak->first_hypothesis = static_cast<uint32_t>(out->size());
  if (!ray) {
    peak->no_ray = true;
    return;
  }
  peak->region = 0;
  for (int m = 0; m < 2; ++m) {
    if (g.mirror_regions[frame.camera][m].Contains(peak->u, peak->v)) {
      peak->region = static_cast<uint8_t>(m + 1);
      break;
    }
  }
  // Try each laser on one ray segment [0, t_max), `path_before` along the ray from the camera.
  auto add = [&](const Ray3d& segment, double t_max, double path_before, PointView view) {
    for (int k = 0; k < laser_count; ++k) {
      const auto t = IntersectRayPlane(segment, planes[k], 1.0);
      if (!t || *t >= t_max) continue;
      const Eigen::Vector3d point = segment.At(*t);
      // Inside the bounding cylinder and clear of both mirrors: nothing is lit behind them
      // (a ray reflected past the other mirror's edge would otherwise go on outside), and
      // near a mirror's glass every camera's reflected rays run close together, so phantom
      // points there would confirm each other. A laser at the floor's height lights the
      // floor, which runs on under the mirrors' feet: that must be a way the peak can have
      // come about, or another laser would take the floor's stripe into the volume.
      const bool floor = cylinder.OnFloor(point);  // below the bottom: never Contains()
      if (!floor &&
          (!cylinder.Contains(point) || g.mirrors[0].SignedDistance(point) < mirror_clearance_mm ||
           g.mirrors[1].SignedDistance(point) < mirror_clearance_mm))
        continue;
      Hypothesis h;
      h.floor = floor;
      h.point = point;
      h.last_direction = segment.direction;
      h.sin_angle = static_cast<float>(std::abs(planes[k].normal.dot(segment.direction)));
      h.path_mm = static_cast<float>(path_before + *t);
      h.key = static_cast<uint8_t>(Key(view, k));
      out->push_back(h);
    }
    // The panels beside the mirrors carry every laser's line too: where the segment meets
    // one before any mirror's glass, on a laser's plane, that laser's line is a way the
    // peak can have come about (else another laser's point in front of the panel takes it).
    double nearest = t_max;
    const PlanarRectangle* panel = nullptr;
    for (const PlanarRectangle& p : g.panels)
      if (const auto t = p.Intersect(segment); t && *t < nearest) {
        nearest = *t;
        panel = &p;
      }
    if (!panel) return;
    for (const PlanarRectangle& m : g.mirror_rectangles)
      if (const auto t = m.Intersect(segment); t && *t < nearest) return;
    const Eigen::Vector3d on_panel = segment.At(nearest);
    for (int k = 0; k < laser_count; ++k) {
      if (std::abs(planes[k].SignedDistance(on_panel)) > kPanelLineMm) continue;
      Hypothesis h;
      h.panel = true;
      h.point = on_panel;
      h.last_direction = segment.direction;
      h.sin_angle = static_cast<float>(std::abs(planes[k].normal.dot(segment.direction)));
      h.path_mm = static_cast<float>(path_before + nearest);
      h.key = static_cast<uint8_t>(Key(view, k));
      out->push_back(h);
    }
  };
  constexpr double kFar = 1e7;
  if (peak->region == 0) {
    add(*ray, kFar, 0.0, PointView::kCenter);
  } else {
    const int a = peak->region - 1;
    const int b = 1 - a;
    const auto t_a = IntersectRayPlane(*ray, g.mirrors[a], 0.0);
    if (t_a) {
      // Something in front of the mirror (an arm reaching into its region), or, where the
      // ray passes below or beside the glass (the region's outline is not the glass), a
      // panel behind it. The mirror's view stays a hypothesis either way: the outline and
      // the corners are both measured.
      const bool meets_glass =
          g.mirror_rectangles.empty() || g.mirror_rectangles[a].Intersect(*ray).has_value();
      add(*ray, meets_glass ? *t_a : kFar, 0.0, PointView::kCenter);
      const Ray3d once{ray->At(*t_a), g.mirrors[a].ReflectDirection(ray->direction)};
      std::optional<double> t_b;
      if (!g.mirror_rectangles.empty()) t_b = g.mirror_rectangles[b].Intersect(once);
      add(once, t_b.value_or(kFar), *t_a, a == 0 ? PointView::kLeft : PointView::kRight);
      if (t_b) {
        const Ray3d twice{once.At(*t_b), g.mirrors[b].ReflectDirection(once.direction)};
        add(twice, kFar, *t_a + *t_b, a == 0 ? PointView::kLeftRight : PointView::kRightLeft);
      }
    }
  }
  peak->hypotheses = static_cast<uint8_t>(out->size() - peak->first_hypothesis);
}

}  // namespace

Hypotheses Hypothesize(const ScanArchive& archive, const Geometry& g, const LaserPlanes& planes,
                       const ReconstructOptions& options,
                       const std::vector<std::optional<Ray3d>>& rays, int threads, PeakTable* table,
                       ReconstructSummary* summary) {
  // Each chunk of frames in its own stretch of the store. A peak has at most a surface and a
  // panel hypothesis per laser on each of its ray's three segments.
  const size_t frame_count = archive.frames.size();
  const size_t most_per_peak = 3 * 2 * static_cast<size_t>(planes.count);
  if (table->peaks.size() * most_per_peak >= std::numeric_limits<uint32_t>::max())
    throw ReconstructError(std::to_string(table->peaks.size()) +
                           " peaks are more than one reconstruction can take");
  Hypotheses hyp(table->peaks.size() * most_per_peak);
  struct Counts {
    size_t panel = 0, no_ray = 0, outside = 0;
  };
  std::vector<Counts> counts(ChunkCount(frame_count, threads));
  ForEachChunk(frame_count, threads, [&](size_t c, size_t begin, size_t end) {
    Hypotheses::Writer out{&hyp, static_cast<uint32_t>(table->frame_first[begin] * most_per_peak),
                           static_cast<uint32_t>(table->frame_first[end] * most_per_peak)};
    Counts& count = counts[c];
    for (size_t f = begin; f < end; ++f) {
      if (!table->used[f]) continue;
      for (uint32_t i = table->frame_first[f]; i < table->frame_first[f + 1]; ++i) {
        PeakState& p = table->peaks[i];
        p.first_hypothesis = out.size();
        if (p.panel) {
          ++count.panel;
          continue;
        }
        if (p.still) continue;  // counted by MarkStillPeaks
        if (!planes.valid[f]) {
          ++count.no_ray;
          continue;
        }
        HypothesizePeak(g, archive.frames[f], planes.per_frame[f], planes.count, options.cylinder,
                        options.mirror_clearance_mm, rays[i], &p, &out);
        if (p.no_ray) {
          ++count.no_ray;
        } else if (p.hypotheses == 0) {
          ++count.outside;
        }
      }
    }
  });
  for (const Counts& count : counts) {
    summary->dropped_panel += count.panel;
    summary->dropped_no_ray += count.no_ray;
    summary->dropped_outside += count.outside;
  }
  return hyp;
}

}  // namespace mirrorscan::reconstruction

#include "host/reconstruction/laser_planes.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/parallel/parallel_for.h"
#include "host/calibration/laser_height.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

LaserPlanes FitLaserPlanes(const ScanArchive& archive, const Calibration& calibration,
                           const std::vector<const CalibrationCamera*>& cameras,
                           const ReconstructOptions& options,
                           const std::vector<std::optional<Ray3d>>& rays, int threads,
                           PeakTable* table, ReconstructSummary* summary) {
  std::vector<PeakState>* peaks = &table->peaks;
  const std::vector<uint32_t>& frame_first = table->frame_first;
  LaserPlanes planes;
  planes.count = LaserCountOf(archive, calibration);
  planes.per_frame.resize(archive.frames.size());
  planes.valid.assign(archive.frames.size(), false);
  LaserHeightSummary& s = summary->laser_height;
  const double readback_offset =
      calibration.lasers ? calibration.lasers->readback_offset_mm.value_or(0.0) : 0.0;

  std::string reason;
  if (options.laser_height_from_panels) {
    try {
      LaserCabinet cabinet =
          LaserCabinetFromCalibration(calibration, "calibration", options.panel_margin_mm);
      // By FrameRecord::camera; a listed camera that took no frame stands in as any other.
      cabinet.cameras.clear();
      const auto any = std::find_if(cameras.begin(), cameras.end(),
                                    [](const CalibrationCamera* c) { return c != nullptr; });
      if (any == cameras.end()) throw ReconstructError("the archive uses no calibrated camera");
      for (const CalibrationCamera* c : cameras)
        cabinet.cameras.push_back(c ? c->camera : (*any)->camera);
      cabinet.laser_count = planes.count;
      if (const auto* lasers = HeaderValue(archive.header, "lasers");
          lasers && lasers->is_object() && lasers->contains("spacing_mm") &&
          (*lasers)["spacing_mm"].is_number())
        cabinet.nominal_spacing_mm = (*lasers)["spacing_mm"].get<double>();
      if (const auto* slide = HeaderValue(archive.header, "slide");
          slide && slide->is_object() && slide->contains("speed_mm_s") &&
          (*slide)["speed_mm_s"].is_number())
        cabinet.nominal_speed_mm_s = (*slide)["speed_mm_s"].get<double>();
      LaserHeightOptions lo;
      if (const auto* start = HeaderValue(archive.header, "start_steady_ns");
          start && start->is_number_integer())
        lo.time_origin_ns = start->get<int64_t>();
      lo.readback_offset_mm = readback_offset;
      lo.readback_tolerance_mm = options.readback_tolerance_mm;
      // The calibration measured the panels; one scan's sweep is no better at it.
      lo.fit_panel_offsets = false;
      lo.threads = threads;
      if (calibration.lasers) lo.normal = calibration.lasers->normal;
      // Each peak's ray is known here: the fit gets the points where one meets a panel before
      // any mirror, found as it would find them, without undistorting every peak again.
      std::vector<std::vector<PanelPoint>> chunks(ChunkCount(archive.frames.size(), threads));
      ForEachChunk(archive.frames.size(), threads, [&](size_t chunk, size_t begin, size_t end) {
        for (size_t f = begin; f < end; ++f) {
          for (uint32_t i = frame_first[f]; i < frame_first[f + 1]; ++i) {
            if (!rays[i]) continue;
            const PeakState& p = (*peaks)[i];
            if (auto point = PanelPointOnRay(cabinet, f, p.u, p.v, *rays[i]))
              chunks[chunk].push_back(*point);
          }
        }
      });
      std::vector<PanelPoint> panel_points;
      for (const auto& chunk : chunks)
        panel_points.insert(panel_points.end(), chunk.begin(), chunk.end());
      const LaserHeightResult result =
          EstimateLaserHeightsFromPoints(archive.frames, cabinet, std::move(panel_points), lo);
      const LaserFit& fit = result.fit;
      for (size_t f = 0; f < archive.frames.size(); ++f) {
        const double t = fit.TimeS(archive.frames[f].timestamp_ns);
        for (int k = 0; k < planes.count; ++k) planes.per_frame[f][k] = fit.PlaneAt(k, t);
        planes.valid[f] = true;
      }
      s.source = "panels";
      s.speed_mm_s = fit.speed_mm_s;
      s.height_at_t0_mm = fit.height_at_t0_mm;
      s.offsets_mm = fit.offset_mm;
      s.normal = fit.normal;
      s.panel_residual_rms_mm = result.residual_rms_mm;
      s.panel_points = result.inliers;
      if (result.readback) {
        s.readback_frames = result.readback->frames;
        s.readback_offset_mm = result.readback->offset_mm;
        s.readback_max_error_mm = result.readback->max_error_mm;
        s.readback_frames_off = result.readback->frames_off;
      }
      for (const std::string& w : result.warnings)
        summary->warnings.push_back("laser height: " + w);
      // The panels' own peaks are laser-height data, not the subject.
      for (const PanelPoint& p : result.points) {
        if (p.laser < 0) continue;
        const auto begin = peaks->begin() + frame_first[p.frame];
        const auto end = peaks->begin() + frame_first[p.frame + 1];
        auto it = std::lower_bound(begin, end, p.u,
                                   [](const PeakState& a, uint16_t u) { return a.u < u; });
        for (; it != end && it->u == p.u; ++it) {
          if (it->v == p.v) it->panel = true;
        }
      }
      return planes;
    } catch (const LaserHeightError& e) {
      reason = e.what();
    } catch (const ConfigError& e) {
      reason = e.what();
    }
  } else {
    reason = "panels not used (option)";
  }

  // Readback: laser 0 at readback − offset, the others at the calibration's offsets.
  if (!calibration.lasers) {
    throw ReconstructError("no laser heights: the panels gave none (" + reason +
                           ") and the calibration has no lasers for the readback");
  }
  const CalibrationLasers& lasers = *calibration.lasers;
  if (planes.count > 1 && lasers.offsets_mm.size() < static_cast<size_t>(planes.count) &&
      lasers.count < planes.count) {
    summary->warnings.push_back("laser offsets above laser 0 assumed at the nominal spacing");
  }
  size_t with_readback = 0;
  for (size_t f = 0; f < archive.frames.size(); ++f) {
    const double readback = archive.frames[f].slide_position_mm;
    if (!std::isfinite(readback)) continue;
    const double h0 = readback - readback_offset;
    for (int k = 0; k < planes.count; ++k) {
      const double offset = k < static_cast<int>(lasers.offsets_mm.size()) ? lasers.offsets_mm[k]
                                                                           : k * lasers.spacing_mm;
      planes.per_frame[f][k] = Plane{lasers.normal, -(h0 + offset)};
    }
    planes.valid[f] = true;
    ++with_readback;
  }
  if (with_readback == 0) {
    throw ReconstructError("no laser heights: the panels gave none (" + reason +
                           ") and no frame has a slide readback");
  }
  s.source = "readback";
  s.reason = reason;
  s.normal = lasers.normal;
  s.readback_frames = with_readback;
  if (!calibration.lasers->readback_offset_mm) {
    summary->warnings.push_back(
        "laser heights from the slide readback with no measured readback offset (0 assumed)");
  }
  summary->warnings.push_back("laser heights from the slide readback: " + reason);
  return planes;
}

}  // namespace mirrorscan::reconstruction

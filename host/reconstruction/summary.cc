#include "host/reconstruction/summary.h"

#include <cstdio>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

namespace {

std::string Format(const char* format, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), format, args...);
  return buffer;
}

}  // namespace

nlohmann::json SummaryJson(const ReconstructSummary& s) {
  nlohmann::json per_view = nlohmann::json::object();
  for (size_t v = 0; v < s.points_per_view.size(); ++v)
    per_view[PointViewName(static_cast<PointView>(v))] = s.points_per_view[v];
  nlohmann::json timings = nlohmann::json::object();
  double total = 0;
  for (const auto& [stage, seconds] : s.timings_s) {
    timings[stage] = seconds;
    total += seconds;
  }
  timings["total"] = total;
  const LaserHeightSummary& l = s.laser_height;
  nlohmann::json icp = {{"ran", s.icp.ran}, {"steps", nlohmann::json::array()}};
  for (const IcpSummary::Step& step : s.icp.steps) {
    icp["steps"].push_back({{"what", step.what},
                            {"rmse_before_mm", step.rmse_before_mm},
                            {"rmse_after_mm", step.rmse_after_mm},
                            {"rotation_deg", step.rotation_deg},
                            {"translation_mm", step.translation_mm},
                            {"applied", step.applied}});
  }
  return {{"archive", {{"complete", s.archive_complete}, {"message", s.archive_message}}},
          {"frames", s.frames},
          {"peaks", s.peaks},
          {"points", s.points},
          {"points_per_camera", s.points_per_camera},
          {"points_per_view", per_view},
          {"points_per_laser", s.points_per_laser},
          {"decided",
           {{"stereo", s.decided_by_stereo},
            {"cylinder", s.decided_by_cylinder},
            {"volume", s.decided_by_volume},
            {"column_count", s.decided_by_column_count},
            {"label_vote", s.decided_by_label_vote}}},
          {"dropped",
           {{"panel", s.dropped_panel},
            {"no_ray", s.dropped_no_ray},
            {"still", s.dropped_still},
            {"outside_volume", s.dropped_outside},
            {"floor", s.dropped_floor},
            {"ambiguous", s.dropped_ambiguous},
            {"conflict", s.dropped_conflict},
            {"unsupported", s.dropped_unsupported},
            {"seen_through", s.dropped_seen_through},
            {"flat_angle", s.dropped_flat_angle},
            {"other_camera", s.dropped_other_camera},
            {"stripe_end", s.dropped_stripe_end},
            {"low_confidence", s.dropped_low_confidence},
            {"off_surface", s.dropped_off_surface},
            {"flat_off_surface", s.dropped_flat_off_surface},
            {"outlier", s.dropped_outlier}}},
          {"double_bounce", s.double_bounce},
          {"laser_height",
           {{"source", l.source},
            {"reason", l.reason},
            {"speed_mm_s", l.speed_mm_s},
            {"height_at_t0_mm", l.height_at_t0_mm},
            {"offsets_mm", l.offsets_mm},
            {"normal", {l.normal.x(), l.normal.y(), l.normal.z()}},
            {"panel_residual_rms_mm", l.panel_residual_rms_mm},
            {"panel_points", l.panel_points},
            {"readback",
             {{"frames", l.readback_frames},
              {"offset_mm", l.readback_offset_mm},
              {"max_error_mm", l.readback_max_error_mm},
              {"frames_off", l.readback_frames_off}}}}},
          {"icp", icp},
          {"warnings", s.warnings},
          {"timings_s", timings}};
}

std::string SummaryText(const ReconstructSummary& s) {
  std::string text =
      Format("%zu points from %zu peaks in %zu frames\n", s.points, s.peaks, s.frames);
  text += "  per camera:";
  for (size_t c = 0; c < s.points_per_camera.size(); ++c)
    text += Format(" %zu: %zu", c, s.points_per_camera[c]);
  text += "\n  per view:";
  for (size_t v = 0; v < s.points_per_view.size(); ++v)
    text += Format(" %s %zu", PointViewName(static_cast<PointView>(v)), s.points_per_view[v]);
  text += "\n  per laser:";
  for (size_t k = 0; k < s.points_per_laser.size(); ++k)
    text += Format(" %zu: %zu", k, s.points_per_laser[k]);
  text += Format(
      "\n  decided by stereo %zu, cylinder %zu, volume %zu, column count %zu, label vote %zu\n",
      s.decided_by_stereo, s.decided_by_cylinder, s.decided_by_volume, s.decided_by_column_count,
      s.decided_by_label_vote);
  text += Format(
      "  dropped: panel %zu, no ray %zu, still %zu, outside volume %zu, floor %zu, ambiguous %zu, "
      "conflict %zu, unsupported %zu, seen through %zu, flat angle %zu, other camera better %zu, "
      "stripe end %zu, outlier %zu, low confidence %zu, off surface %zu, flat off surface %zu\n",
      s.dropped_panel, s.dropped_no_ray, s.dropped_still, s.dropped_outside, s.dropped_floor,
      s.dropped_ambiguous, s.dropped_conflict, s.dropped_unsupported, s.dropped_seen_through,
      s.dropped_flat_angle, s.dropped_other_camera, s.dropped_stripe_end, s.dropped_outlier,
      s.dropped_low_confidence, s.dropped_off_surface, s.dropped_flat_off_surface);
  const LaserHeightSummary& l = s.laser_height;
  text += Format("  laser heights from %s", l.source.c_str());
  if (l.source == "panels") {
    text += Format(" (%zu points, rms %.3f mm, speed %.3f mm/s)", l.panel_points,
                   l.panel_residual_rms_mm, l.speed_mm_s);
    if (l.readback_frames)
      text += Format("; readback max error %.3f mm over %zu frames (%zu off)",
                     l.readback_max_error_mm, l.readback_frames, l.readback_frames_off);
  } else {
    text += " (" + l.reason + ")";
  }
  text += "\n";
  if (s.icp.ran) {
    for (const IcpSummary::Step& step : s.icp.steps)
      text += Format("  icp %s: rmse %.3f -> %.3f mm, %.4f deg, %.3f mm%s\n", step.what.c_str(),
                     step.rmse_before_mm, step.rmse_after_mm, step.rotation_deg,
                     step.translation_mm, step.applied ? "" : " (not applied)");
  }
  double total = 0;
  text += "  timings:";
  for (const auto& [stage, seconds] : s.timings_s) {
    text += Format(" %s %.3f s,", stage.c_str(), seconds);
    total += seconds;
  }
  text += Format(" total %.3f s\n", total);
  for (const std::string& w : s.warnings) text += "  warning: " + w + "\n";
  return text;
}

}  // namespace mirrorscan::reconstruction

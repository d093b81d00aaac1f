#include "host/cli/calibrate_lasers_command.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config/calibration.h"
#include "common/scan_format/scan_format.h"
#include "host/board/board_json.h"
#include "host/calibration/calibrate.h"
#include "host/calibration/laser_height.h"

namespace mirrorscan::cli {

namespace {

struct LasersOptions {
  std::string scan;
  std::string calibration;
  std::string out;
  std::string calibration_out;
  std::string board;
  double panel_margin_mm = 120.0;
  std::optional<double> readback_offset_mm;  // default: the calibration's, else 0
  double readback_tolerance_mm = 1.0;
  bool no_tilt = false;
  bool keep_panel_offsets = false;
  bool json = false;
};

nlohmann::json NumberOrNull(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

// The archive's cameras by record index, matched to the calibration's by name.
std::vector<Camera> CamerasOf(const ScanArchive& archive, const Calibration& calibration,
                              const std::string& scan, const std::string& calibration_file) {
  std::vector<Camera> cameras;
  const nlohmann::json& header = archive.header;
  if (!header.contains("cameras") || !header["cameras"].is_array()) {
    for (const CalibrationCamera& c : calibration.cameras) cameras.push_back(c.camera);
    return cameras;
  }
  for (const nlohmann::json& entry : header["cameras"]) {
    const std::string name =
        entry.is_object() && entry.contains("name") && entry["name"].is_string()
            ? entry["name"].get<std::string>()
            : "";
    const CalibrationCamera* camera = calibration.FindCamera(name);
    if (!camera) {
      throw std::runtime_error(scan + ": camera \"" + name + "\" is not in " + calibration_file);
    }
    cameras.push_back(camera->camera);
  }
  return cameras;
}

nlohmann::json ResultJson(const LaserHeightResult& r, const LasersOptions& o, double limit_mm,
                          double expected_readback_offset_mm,
                          const std::vector<std::string>& failures) {
  const LaserFit& fit = r.fit;
  nlohmann::json panel_offsets = nlohmann::json::array();
  for (const PanelOffset& offset : r.panel_offsets) {
    panel_offsets.push_back({{"name", offset.name},
                             {"assumed_mm", offset.assumed_mm},
                             {"measured_mm", NumberOrNull(offset.measured_mm)},
                             {"std_error_mm", NumberOrNull(offset.std_error_mm)},
                             {"inliers", offset.inliers},
                             {"limit_mm", limit_mm},
                             {"ok", offset.WithinLimit(limit_mm)}});
  }
  nlohmann::json frames = nlohmann::json::array();
  for (const FrameLaserHeights& f : r.frames) {
    frames.push_back({{"frame", f.frame},
                      {"camera", f.camera},
                      {"sequence", f.sequence},
                      {"time_s", f.time_s},
                      {"heights_mm", f.height_mm},
                      {"panel_points", f.panel_points},
                      {"measured_mm", NumberOrNull(f.measured_mm)},
                      {"readback_mm", NumberOrNull(f.readback_mm)}});
  }
  nlohmann::json readback = nullptr;
  if (r.readback) {
    readback = {{"frames", r.readback->frames},
                {"offset_mm", r.readback->offset_mm},
                {"expected_offset_mm", expected_readback_offset_mm},
                {"max_error_mm", r.readback->max_error_mm},
                {"frames_off", r.readback->frames_off},
                {"tolerance_mm", o.readback_tolerance_mm},
                {"speed_mm_s", r.readback->speed_mm_s}};
  }
  const Eigen::Vector2d tilt = fit.TiltDeg();
  return {{"schema", "mirrorscan.lasers"},
          {"version", 1},
          {"ok", failures.empty()},
          {"failures", failures},
          {"scan", o.scan},
          {"calibration", o.calibration},
          {"note",
           "laser k at t = (timestamp - time_origin_ns) s: normal · x = height_at_t0 + "
           "speed·t + offsets[k]"},
          {"time_origin_ns", fit.time_origin_ns},
          {"count", fit.offset_mm.size()},
          {"height_at_t0_mm", fit.height_at_t0_mm},
          {"speed_mm_s", fit.speed_mm_s},
          {"normal", {fit.normal.x(), fit.normal.y(), fit.normal.z()}},
          {"tilt_deg", {tilt.x(), tilt.y()}},
          {"offsets_mm", fit.offset_mm},
          {"spacing_mm", fit.spacing_mm},
          {"residual_rms_mm", r.residual_rms_mm},
          {"residual_max_mm", r.residual_max_mm},
          {"frame_rms_mm", r.frame_rms_mm},
          {"frame_max_mm", r.frame_max_mm},
          {"panel_points", r.candidates},
          {"inliers", r.inliers},
          {"inliers_per_laser", r.inliers_per_laser},
          {"panel_offsets", panel_offsets},
          {"readback", readback},
          {"warnings", r.warnings},
          {"frames", frames}};
}

void WriteText(const std::string& path, const std::string& option, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
  if (!out.flush()) throw std::runtime_error(option + " " + path + ": cannot write");
}

void Run(const LasersOptions& o) {
  const Calibration calibration = Calibration::Load(o.calibration);
  const ScanArchive archive = ReadScanFile(o.scan);
  if (archive.header.is_null())
    throw std::runtime_error(o.scan + ": no readable header (" + archive.report.message + ")");
  if (!archive.report.complete)
    std::fprintf(stderr, "calibrate-lasers: %s: %s\n", o.scan.c_str(),
                 archive.report.message.c_str());
  if (o.panel_margin_mm <= 0) throw std::runtime_error("--panel-margin: must be positive");
  if (o.readback_tolerance_mm <= 0)
    throw std::runtime_error("--readback-tolerance: must be positive");

  LaserCabinet cabinet = LaserCabinetFromCalibration(calibration, o.calibration, o.panel_margin_mm);
  cabinet.cameras = CamerasOf(archive, calibration, o.scan, o.calibration);
  // What the device used for this scan wins over the calibration's nominal values.
  const nlohmann::json& header = archive.header;
  if (header.contains("lasers") && header["lasers"].is_object()) {
    const nlohmann::json& lasers = header["lasers"];
    if (lasers.contains("count") && lasers["count"].is_number_integer())
      cabinet.laser_count = lasers["count"].get<int>();
    if (lasers.contains("spacing_mm") && lasers["spacing_mm"].is_number())
      cabinet.nominal_spacing_mm = lasers["spacing_mm"].get<double>();
  }
  if (header.contains("slide") && header["slide"].is_object() &&
      header["slide"].contains("speed_mm_s") && header["slide"]["speed_mm_s"].is_number())
    cabinet.nominal_speed_mm_s = header["slide"]["speed_mm_s"].get<double>();

  const calibration::CalibrationLimits limits =
      o.board.empty() ? calibration::CalibrationLimits{}
                      : host_board::CalibrationSettingsFromBoard(o.board).limits;
  LaserHeightOptions options;
  if (header.contains("start_steady_ns") && header["start_steady_ns"].is_number_integer())
    options.time_origin_ns = header["start_steady_ns"].get<int64_t>();
  // A readback offset measured at calibration is what later scans are checked against.
  options.readback_offset_mm = o.readback_offset_mm.value_or(
      calibration.lasers ? calibration.lasers->readback_offset_mm.value_or(0.0) : 0.0);
  options.readback_tolerance_mm = o.readback_tolerance_mm;
  options.fit_tilt = !o.no_tilt;
  options.fit_panel_offsets = !o.keep_panel_offsets;
  std::fprintf(stderr, "calibrate-lasers: %zu frames, %d laser(s); fitting...\n",
               archive.frames.size(), cabinet.laser_count);
  const LaserHeightResult result = EstimateLaserHeights(archive.frames, cabinet, options);
  for (const std::string& warning : result.warnings)
    std::fprintf(stderr, "calibrate-lasers: warning: %s\n", warning.c_str());

  const std::vector<std::string> failures =
      PanelOffsetFailures(result, limits.max_panel_offset_error_mm);
  const nlohmann::json json =
      ResultJson(result, o, limits.max_panel_offset_error_mm, options.readback_offset_mm, failures);
  WriteText(o.out, "--out", json.dump(2) + "\n");
  if (!failures.empty()) {
    for (const std::string& failure : failures)
      std::fprintf(stderr, "calibrate-lasers: FAIL: %s\n", failure.c_str());
    throw std::runtime_error("laser calibration failed its checks (" + o.out + ")" +
                             (o.calibration_out.empty() ? "" : "; no calibration written"));
  }
  if (!o.calibration_out.empty()) {
    Calibration updated = calibration;
    CalibrationLasers lasers;
    lasers.count = static_cast<int>(result.fit.offset_mm.size());
    lasers.spacing_mm =
        result.fit.spacing_mm > 0 ? result.fit.spacing_mm : cabinet.nominal_spacing_mm;
    lasers.normal = result.fit.normal;
    lasers.height_at_t0_mm = result.fit.height_at_t0_mm;
    lasers.speed_mm_s = result.fit.speed_mm_s;
    lasers.offsets_mm = result.fit.offset_mm;
    if (result.readback) lasers.readback_offset_mm = result.readback->offset_mm;
    updated.lasers = lasers;
    // The panels are built from the mirrors in order.
    for (size_t i = 0; i < result.panel_offsets.size(); ++i)
      updated.mirrors.at(i).panel_offset_mm = result.panel_offsets[i].used_mm();
    // Validated as any reader will (e.g. lasers out of order), before it is written.
    const nlohmann::json updated_json = updated.ToJson();
    Calibration::Parse(updated_json, o.calibration_out);
    WriteText(o.calibration_out, "--calibration-out", updated_json.dump(2) + "\n");
  }
  if (o.json) {
    std::printf("%s\n", json.dump(2).c_str());
    return;
  }
  const LaserFit& fit = result.fit;
  const Eigen::Vector2d tilt = fit.TiltDeg();
  std::printf("laser 0 at t = 0: %.3f mm, speed %.4f mm/s, tilt %.4f° about x, %.4f° about y\n",
              fit.height_at_t0_mm, fit.speed_mm_s, tilt.x(), tilt.y());
  for (size_t k = 1; k < fit.offset_mm.size(); ++k)
    std::printf("laser %zu: %.3f mm above laser 0\n", k, fit.offset_mm[k]);
  std::printf(
      "%zu of %zu panel points on a laser line; residual RMS %.3f mm (max %.3f); "
      "per-frame heights vs line RMS %.3f mm (max %.3f)\n",
      result.inliers, result.candidates, result.residual_rms_mm, result.residual_max_mm,
      result.frame_rms_mm, result.frame_max_mm);
  for (const PanelOffset& offset : result.panel_offsets) {
    if (offset.measured())
      std::printf("%s: %.3f mm behind its mirror (± %.3f; calibration %.3f)\n", offset.name.c_str(),
                  offset.measured_mm, offset.std_error_mm, offset.assumed_mm);
    else
      std::printf("%s: %.3f mm behind its mirror (calibration's; not measured)\n",
                  offset.name.c_str(), offset.assumed_mm);
  }
  if (result.readback) {
    std::printf("readback: %zu frames, readback − laser 0 median %.3f mm, max deviation %.3f mm\n",
                result.readback->frames, result.readback->offset_mm, result.readback->max_error_mm);
  }
  std::printf("wrote %s\n", o.out.c_str());
}

}  // namespace

void AddCalibrateLasersCommand(CLI::App& app) {
  auto options = std::make_shared<LasersOptions>();
  auto* cmd = app.add_subcommand(
      "calibrate-lasers",
      "Laser planes for every frame of a scan, from the laser lines on the panels beside the "
      "mirrors (constant slide speed; per-laser offsets, tilt and, with two cameras, the "
      "panels' offsets fitted)");
  cmd->add_option("SCAN", options->scan, "Scan archive (.mscan)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--calibration", options->calibration, "calibration.json (cameras, mirrors)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", options->out, "Write lasers.json (the fit and every frame's heights)")
      ->required();
  cmd->add_option("--calibration-out", options->calibration_out,
                  "Also write the calibration with its \"lasers\" and measured panel offsets set "
                  "from this scan's fit (only when its checks pass)");
  cmd->add_option("--board", options->board,
                  "board.json whose calibration.limits.max_panel_offset_error_mm to check "
                  "(default 1 mm)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--panel-margin", options->panel_margin_mm,
                  "How far the panels reach beyond each mirror's outer edge and top, mm")
      ->capture_default_str();
  cmd->add_option("--readback-offset", options->readback_offset_mm,
                  "Expected slide readback minus laser 0's height, mm (default: the "
                  "calibration's lasers.readback_offset_mm, else 0)");
  cmd->add_option("--readback-tolerance", options->readback_tolerance_mm,
                  "Warn when the readback is further than this from the fitted line, mm")
      ->capture_default_str();
  cmd->add_flag("--no-tilt", options->no_tilt, "Assume level laser planes");
  cmd->add_flag("--keep-panel-offsets", options->keep_panel_offsets,
                "Use the calibration's panel offsets, do not measure them");
  cmd->add_flag("--json", options->json, "Print lasers.json");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

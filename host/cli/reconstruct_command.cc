#include "host/cli/reconstruct_command.h"

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "common/config/calibration.h"
#include "common/mesh/cloud_io.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "host/board/board_json.h"
#include "host/cli/exit_status.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::cli {

namespace {

struct ReconstructCliOptions {
  std::string scan;
  std::string calibration;
  std::string out;
  std::string board;
  bool json = false;
  bool mismatch_ok = false;
  bool readback = false;
  bool no_smooth = false;
  bool no_outliers = false;
  bool no_surface_check = false;
  bool drop_stripe_ends = false;
  double prefer_camera = -1;
  bool icp = false;
  bool no_stereo = false;
  bool no_free_space = false;
  double core_radius_mm = -1;
  double stereo_max_mm = -1;
  int threads = 0;
  double radius_mm = -1, bottom_mm = -1e9, top_mm = -1e9;
  double min_angle_deg = -1;
  double min_confidence = -1;
};

void Run(const ReconstructCliOptions& o) {
  const Calibration calibration = Calibration::Load(o.calibration);
  const ScanArchive archive = ReadScanFile(o.scan);
  if (!archive.report.complete)
    std::fprintf(stderr, "reconstruct: %s: %s\n", o.scan.c_str(), archive.report.message.c_str());

  reconstruction::ReconstructOptions options;
  if (!o.board.empty()) options.cylinder = host_board::BoundingCylinderFromBoard(o.board);
  if (o.radius_mm > 0) options.cylinder.radius_mm = o.radius_mm;
  if (o.core_radius_mm > 0) {
    if (o.core_radius_mm > options.cylinder.radius_mm)
      throw std::runtime_error("--cylinder-core-radius must not exceed the cylinder's radius");
    options.cylinder.core_radius_mm = o.core_radius_mm;
  }
  if (o.bottom_mm > -1e9) options.cylinder.bottom_mm = o.bottom_mm;
  if (o.top_mm > -1e9) options.cylinder.top_mm = o.top_mm;
  if (options.cylinder.top_mm <= options.cylinder.bottom_mm)
    throw std::runtime_error("--cylinder-top must be above --cylinder-bottom");
  if (o.min_angle_deg >= 0) options.min_ray_plane_angle_deg = o.min_angle_deg;
  options.allow_calibration_mismatch = o.mismatch_ok;
  options.calibration_file_sha256 = protocol::Sha256::HexOfFile(o.calibration);
  options.laser_height_from_panels = !o.readback;
  options.smooth_3x3 = !o.no_smooth;
  options.remove_outliers = !o.no_outliers;
  options.surface_check = !o.no_surface_check;
  options.drop_stripe_ends = o.drop_stripe_ends;
  if (o.prefer_camera >= 0) options.prefer_camera_ratio = o.prefer_camera;
  options.icp = o.icp;
  options.stereo = !o.no_stereo;
  options.free_space_check = !o.no_free_space;
  if (o.min_confidence >= 0) options.min_confidence = o.min_confidence;
  if (o.stereo_max_mm > 0) options.stereo_max_mm = o.stereo_max_mm;
  options.threads = o.threads;
  try {
    options.Validate();
  } catch (const std::invalid_argument& e) {
    throw CommandExit(kExitUsage, std::string("reconstruct: ") + e.what());
  }
  std::string last_stage;
  options.progress = [&](const std::string& stage, double fraction) {
    if (o.json) return;
    if (stage != last_stage && !last_stage.empty()) std::fprintf(stderr, "\n");
    last_stage = stage;
    std::fprintf(stderr, "\rreconstruct: %s %3.0f%%", stage.c_str(), 100.0 * fraction);
    if (stage == "done") std::fprintf(stderr, "\n");
  };
  reconstruction::Reconstruction result;
  try {
    result = reconstruction::Reconstruct(archive, calibration, options);
  } catch (const std::exception&) {
    if (!last_stage.empty() && last_stage != "done") std::fprintf(stderr, "\n");
    throw;
  }
  WritePointCloud(o.out, result.cloud);
  for (const std::string& w : result.summary.warnings)
    std::fprintf(stderr, "reconstruct: warning: %s\n", w.c_str());
  if (o.json) {
    nlohmann::json json = reconstruction::SummaryJson(result.summary);
    json["out"] = o.out;
    std::printf("%s\n", json.dump(2).c_str());
  } else {
    std::printf("%s", reconstruction::SummaryText(result.summary).c_str());
    std::printf("wrote %s\n", o.out.c_str());
  }
}

// " (default X)" from the options' own defaults, so the help cannot drift from them.
std::string DefaultIs(double value) {
  char text[64];
  std::snprintf(text, sizeof text, " (default %g)", value);
  return text;
}

}  // namespace

void AddReconstructCommand(CLI::App& app) {
  auto o = std::make_shared<ReconstructCliOptions>();
  const reconstruction::ReconstructOptions defaults;
  auto* cmd = app.add_subcommand(
      "reconstruct",
      "Every laser peak of a scan to a 3D point (binary PLY with normals, camera, view, laser, "
      "frame, column, confidence); a summary on stdout");
  cmd->add_option("SCAN", o->scan, "Scan archive (.mscan)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--calibration", o->calibration, "calibration.json of this cabinet")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", o->out, "points.ply to write")->required();
  cmd->add_option("--board", o->board, "board.json whose reconstruction.bounding_cylinder to use")
      ->check(CLI::ExistingFile);
  cmd->add_option("--cylinder-radius", o->radius_mm,
                  "Bounding cylinder radius, mm: no point beyond it" +
                      DefaultIs(defaults.cylinder.radius_mm))
      ->check(CLI::PositiveNumber);
  cmd->add_option("--cylinder-core-radius", o->core_radius_mm,
                  "Its core, mm: one hypothesis there decides a peak alone" +
                      DefaultIs(defaults.cylinder.core_radius_mm))
      ->check(CLI::PositiveNumber);
  cmd->add_option("--cylinder-bottom", o->bottom_mm,
                  "Bounding cylinder bottom, mm" + DefaultIs(defaults.cylinder.bottom_mm));
  cmd->add_option("--cylinder-top", o->top_mm,
                  "Bounding cylinder top, mm" + DefaultIs(defaults.cylinder.top_mm));
  cmd->add_option("--min-angle", o->min_angle_deg,
                  "Drop points whose ray meets the laser plane flatter than this, degrees" +
                      DefaultIs(defaults.min_ray_plane_angle_deg))
      ->check(CLI::Range(0.0, 89.0));
  cmd->add_flag("--calibration-mismatch-ok", o->mismatch_ok,
                "Use the calibration even if the archive was made with another one");
  cmd->add_flag("--readback", o->readback,
                "Laser heights from the slide readback, not from the panel lines");
  cmd->add_flag("--no-smooth", o->no_smooth, "No 3x3 averaging in (column, frame)");
  cmd->add_flag("--no-outliers", o->no_outliers, "Keep statistical outliers");
  cmd->add_flag("--no-surface-check", o->no_surface_check,
                "Keep weak points (stripe ends, grazing rays) that lie off the surface the "
                "confident points around them show");
  cmd->add_flag("--drop-stripe-ends", o->drop_stripe_ends,
                "Drop the last 2 columns of every stripe (they only get a low confidence)");
  cmd->add_option("--prefer-camera", o->prefer_camera,
                  "Drop a camera's points where another meets the laser planes this many times "
                  "more squarely (default 0: keep every camera's)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-stereo", o->no_stereo,
                "Do not decide laser and view by what the other camera sees");
  cmd->add_option("--stereo-max-mm", o->stereo_max_mm,
                  "How near another camera's point of the same laser must be, mm" +
                      DefaultIs(defaults.stereo_max_mm))
      ->check(CLI::PositiveNumber);
  cmd->add_option("--min-confidence", o->min_confidence,
                  "Drop points whose confidence is below this (default 0: keep all)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--no-free-space-check", o->no_free_space,
                "Keep points that other lasers at their pixel, or other views, see through");
  cmd->add_flag("--icp", o->icp, "Refine the mirror views against the centre view (ICP)");
  cmd->add_option("--threads", o->threads,
                  "Worker threads (default 0: every core; the cloud is the same for any number)")
      ->check(CLI::Range(0, 256));
  cmd->add_flag("--json", o->json, "Print the summary as JSON (no progress)");
  cmd->callback([o] { Run(*o); });
}

}  // namespace mirrorscan::cli

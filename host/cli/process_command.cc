#include "host/cli/process_command.h"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/version.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/config/calibration.h"
#include "common/config/json_reader.h"
#include "common/protocol/protocol.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "host/board/board_json.h"
#include "host/cli/exit_status.h"
#include "host/cli/mesh_command.h"
#include "host/cli/progress.h"
#include "host/client/device_client.h"
#include "host/measurement/measure.h"
#include "host/measurement/preview.h"
#include "host/meshing/meshing.h"
#include "host/meshing/preview.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct ProcessOptions {
  std::string scan;
  std::string calibration;
  std::string out;
  std::string formats = "ply";
  std::string board;
  meshing::MeshingOptions meshing;
  bool calibration_mismatch_ok = false;
  bool no_previews = false;
  int preview_height = 900;
  bool json = false;
  std::string upload;  // host:port of the device to put the results on
  std::string token;
};

// Everything `process` writes; removed first so a failed run leaves no stale result
// (least of all a mesh from an earlier scan) beside its summary.
const char* const kOutputs[] = {"points.ply",
                                "mesh.ply",
                                "mesh.obj",
                                "mesh.stl",
                                "mesh.mtl",
                                "summary.json",
                                "measurements.json",
                                "preview-measurements.png",
                                "preview-front.png",
                                "preview-back.png",
                                "preview-left.png",
                                "preview-right.png",
                                "preview-cloud-views.png",
                                "preview-cloud-cameras.png"};

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

nlohmann::json FileInput(const fs::path& file) {
  return {{"path", file.string()},
          {"bytes", fs::file_size(file)},
          {"sha256", protocol::Sha256::HexOfFile(file)}};
}

void WriteJsonFile(const fs::path& path, const nlohmann::json& json) {
  std::ofstream out(path);
  out << json.dump(2) << "\n";
  if (!out) throw CommandExit(kExitFailure, "cannot write " + path.string());
}

void WritePng(const fs::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) {
    throw CommandExit(kExitFailure, "cannot write " + path.string());
  }
}

std::vector<std::string> CameraNames(const nlohmann::json& header, size_t count) {
  std::vector<std::string> names;
  for (size_t i = 0; i < count; ++i) {
    std::string name = "camera " + std::to_string(i);
    if (header.is_object() && header.contains("cameras") && header["cameras"].is_array() &&
        i < header["cameras"].size() && header["cameras"][i].is_object()) {
      name = header["cameras"][i].value("name", name);
    }
    names.push_back(name);
  }
  return names;
}

// The single-bounce views a cloud must hold for a body: at least two of the three, or the
// mesh would be a shell of one side.
void CheckViews(const reconstruction::ReconstructSummary& summary) {
  const size_t total = summary.points;
  std::vector<std::string> present;
  for (int view = 0; view < 3; ++view) {
    const size_t count =
        view < static_cast<int>(summary.points_per_view.size()) ? summary.points_per_view[view] : 0;
    // On the mannequin the mirror views hold 24 % of the points each; with black mirrors
    // 2.5 % (peaks near the mirror edges).
    if (count >= 0.05 * total && count > 0) {
      present.push_back(
          reconstruction::PointViewName(static_cast<reconstruction::PointView>(view)));
    }
  }
  if (present.size() < 2) {
    throw CommandExit(
        kExitFailure,
        "the cloud covers " +
            (present.empty() ? std::string("no view") : "only the " + present[0] + " view") + " (" +
            std::to_string(total) +
            " points): a body needs the centre and mirror views; are the mirrors "
            "in the calibration's view regions?");
  }
}

// Puts the folder's results on the device the scan came from: every file of
// protocol::ResultKinds that this run wrote, summary.json last (the device's page takes a
// summary as "processed"). A failed run sends its summary.json alone (the reason).
void Upload(const ProcessOptions& o, const fs::path& out, const nlohmann::json& summary) {
  const std::string id = summary.value("scan_id", "");
  if (!protocol::IsValidScanId(id)) {
    throw CommandExit(kExitUpload, "--upload: the archive names no device scan id (\"" + id +
                                       "\"); was it fetched from a device?");
  }
  std::vector<std::string> names;
  if (summary.value("ok", false)) {
    for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
      if (kind.name != "summary.json" && fs::is_regular_file(out / std::string(kind.name))) {
        names.push_back(std::string(kind.name));
      }
    }
  }
  names.push_back("summary.json");
  try {
    client::DeviceClient device(o.upload, o.token);
    for (const std::string& name : names) device.PutResult(id, name, out / name);
  } catch (const client::DeviceError& e) {
    throw CommandExit(kExitUpload, std::string("--upload: ") + e.what());
  }
  std::fprintf(stderr, "process: %zu result(s) of %s uploaded to %s\n", names.size(), id.c_str(),
               o.upload.c_str());
}

// Before the minutes of processing: the device answers, has this scan, and takes the token
// (on a board with open reads a wrong token shows only at the upload).
void CheckUploadTarget(const ProcessOptions& o, const std::string& id) {
  if (!protocol::IsValidScanId(id)) {
    throw CommandExit(kExitUpload, "--upload: the archive names no device scan id (\"" + id +
                                       "\"); was it fetched from a device?");
  }
  try {
    client::DeviceClient(o.upload, o.token).Get(id);
  } catch (const client::DeviceError& e) {
    throw CommandExit(kExitUpload, std::string("--upload: ") + e.what() + "; nothing processed");
  }
}

// After a failed run: the failure is what the exit status reports, the upload's own
// trouble only a warning.
void UploadFailure(const ProcessOptions& o, const fs::path& out, const nlohmann::json& summary) {
  try {
    Upload(o, out, summary);
  } catch (const CommandExit& e) {
    std::fprintf(stderr, "process: warning: %s\n", e.what());
  }
}

void Run(const ProcessOptions& o) {
  const auto start = Clock::now();
  const std::vector<std::string> formats = ParseFormats(o.formats);
  try {
    o.meshing.Validate();
  } catch (const std::invalid_argument& e) {
    throw CommandExit(kExitUsage, e.what());
  }
  std::error_code error;
  for (const auto& [flag, file] : {std::pair{"SCAN", o.scan}, {"--calibration", o.calibration}}) {
    if (!fs::is_regular_file(file, error)) {
      throw CommandExit(kExitUsage, std::string(flag) + " " + file + ": no such file");
    }
  }
  if (!o.board.empty() && !fs::is_regular_file(o.board, error)) {
    throw CommandExit(kExitUsage, "--board " + o.board + ": no such file");
  }
  const fs::path out(o.out);
  fs::create_directories(out, error);
  if (!fs::is_directory(out, error)) {
    throw CommandExit(kExitUsage, "--out " + o.out + ": cannot create the directory");
  }
  for (const char* name : kOutputs) fs::remove(out / name, error);

  nlohmann::json summary = {
      {"ok", false},
      {"versions",
       {{"mirrorscan", MIRRORSCAN_VERSION},
        {"open3d", meshing::Open3dVersion()},
        {"embree", meshing::EmbreeVersion()},
        {"opencv", CV_VERSION}}},
      {"inputs", {{"archive", FileInput(o.scan)}, {"calibration", FileInput(o.calibration)}}},
      {"options",
       {{"formats", formats},
        {"watertight", o.meshing.watertight},
        {"voxel_mm", o.meshing.voxel_mm},
        {"cell_mm", o.meshing.cell_mm},
        {"depth", o.meshing.depth},
        {"threads", o.meshing.threads},
        {"trim_distance_mm", o.meshing.trim_distance_mm}}},
      {"timings_s", nlohmann::json::object()},
      {"warnings", nlohmann::json::array()},
      // Filled in from host/measurement once the mesh is measured.
      {"measurements", nullptr}};
  if (!o.board.empty()) summary["inputs"]["board"] = FileInput(o.board);
  nlohmann::json& timings = summary["timings_s"];
  nlohmann::json& warnings = summary["warnings"];
  std::vector<std::string> written;
  Progress progress("process");

  auto finish = [&](bool ok, const std::string& reason) {
    progress.Done();
    summary["ok"] = ok;
    if (!ok) summary["reason"] = reason;
    summary["outputs"] = written;
    timings["total"] = SecondsSince(start);
    WriteJsonFile(out / "summary.json", summary);
  };

  try {
    auto stage_start = Clock::now();
    progress.Stage("reading the archive");
    ScanArchive archive;
    Calibration calibration;
    try {
      archive = ReadScanFile(o.scan);
      calibration = Calibration::Load(o.calibration);
    } catch (const ScanFormatError& e) {
      throw CommandExit(kExitUsage, e.what());
    } catch (const ConfigError& e) {
      throw CommandExit(kExitUsage, e.what());
    }
    const std::string scan_id =
        archive.header.is_object()
            ? archive.header.value("scan_id", fs::path(o.scan).stem().string())
            : fs::path(o.scan).stem().string();
    summary["scan_id"] = scan_id;
    if (!o.upload.empty()) CheckUploadTarget(o, scan_id);
    summary["archive"] = {{"complete", archive.report.complete},
                          {"frames", archive.report.frames},
                          {"peaks", archive.report.peaks},
                          {"message", archive.report.message}};
    if (!archive.report.complete) warnings.push_back(o.scan + ": " + archive.report.message);
    timings["read"] = SecondsSince(stage_start);

    stage_start = Clock::now();
    progress.Stage("reconstruction");
    reconstruction::ReconstructOptions reconstruct_options;
    if (!o.board.empty()) {
      try {
        reconstruct_options.cylinder = host_board::BoundingCylinderFromBoard(o.board);
      } catch (const ConfigError& e) {
        throw CommandExit(kExitUsage, e.what());
      }
    }
    reconstruct_options.allow_calibration_mismatch = o.calibration_mismatch_ok;
    reconstruct_options.calibration_file_sha256 = summary["inputs"]["calibration"]["sha256"];
    reconstruct_options.progress = [&](const std::string&, double fraction) {
      progress.Update(fraction);
    };
    reconstruction::Reconstruction reconstruction;
    try {
      reconstruction = reconstruction::Reconstruct(archive, calibration, reconstruct_options);
    } catch (const reconstruction::ReconstructError& e) {
      throw CommandExit(kExitFailure, e.what());
    }
    const nlohmann::json header = archive.header;
    archive = ScanArchive();  // the frames are not needed any more
    const reconstruction::ReconstructSummary& reconstructed = reconstruction.summary;
    summary["reconstruction"] = reconstruction::SummaryJson(reconstructed);
    for (const auto& warning : reconstructed.warnings) warnings.push_back(warning);
    timings["reconstruct"] = SecondsSince(stage_start);
    for (const auto& [name, seconds] : reconstructed.timings_s) {
      timings["reconstruct." + name] = seconds;
    }
    stage_start = Clock::now();
    reconstruction::WritePly(out / "points.ply", reconstruction.cloud);
    written.push_back((out / "points.ply").string());
    timings["write_points"] = SecondsSince(stage_start);
    if (reconstruction.cloud.points.size() < static_cast<size_t>(o.meshing.min_points)) {
      throw CommandExit(kExitFailure,
                        "no usable points: " + std::to_string(reconstruction.cloud.points.size()) +
                            " in the cloud, at least " + std::to_string(o.meshing.min_points) +
                            " needed for a surface (" + std::to_string(reconstructed.peaks) +
                            " peaks in the archive)");
    }
    CheckViews(reconstructed);

    stage_start = Clock::now();
    progress.Stage("Poisson surface");
    meshing::OrientedCloud cloud;
    std::vector<uint8_t> views, cameras;
    cloud.points.reserve(reconstruction.cloud.points.size());
    cloud.normals.reserve(reconstruction.cloud.points.size());
    size_t camera_count = 0;
    for (const auto& point : reconstruction.cloud.points) {
      cloud.points.push_back(point.point_in_world.cast<double>());
      cloud.normals.push_back(point.normal.cast<double>());
      views.push_back(static_cast<uint8_t>(point.view));
      cameras.push_back(point.camera);
      camera_count = std::max<size_t>(camera_count, point.camera + 1u);
    }
    reconstruction.cloud = {};
    meshing::MeshingResult meshed;
    try {
      meshed = meshing::MeshCloud(cloud, o.meshing);
    } catch (const meshing::MeshingError& e) {
      throw CommandExit(kExitFailure, std::string("no usable mesh: ") + e.what());
    }
    summary["mesh"] = MeshingJson(meshed);
    for (const auto& warning : meshed.warnings) warnings.push_back(warning);
    timings["mesh"] = SecondsSince(stage_start);
    timings["mesh.downsample"] = meshed.downsample_s;
    timings["mesh.poisson"] = meshed.poisson_s;
    timings["mesh.trim"] = meshed.trim_s;

    stage_start = Clock::now();
    progress.Stage("writing the mesh");
    for (const auto& file : WriteMeshFormats(meshed.mesh, out / "mesh.ply", formats)) {
      written.push_back(file.string());
    }
    timings["write_mesh"] = SecondsSince(stage_start);

    if (!o.no_previews) {
      stage_start = Clock::now();
      progress.Stage("previews");
      meshing::PreviewOptions preview_options;
      preview_options.height_px = o.preview_height;
      preview_options.title = scan_id;
      int done = 0;
      for (meshing::Side side : meshing::kAllSides) {
        const fs::path file = out / (std::string("preview-") + meshing::SideName(side) + ".png");
        WritePng(file, meshing::RenderMeshPreview(meshed.mesh, side, preview_options).image);
        written.push_back(file.string());
        progress.Update(++done / 6.0);
      }
      // The clouds framed like the mesh, front and back side by side.
      const std::vector<std::string> view_names = {"centre", "left mirror", "right mirror",
                                                   "left-right", "right-left"};
      const std::vector<std::string> camera_names = CameraNames(header, camera_count);
      for (const auto& [name, labels, names] :
           {std::tuple{"views", &views, &view_names}, {"cameras", &cameras, &camera_names}}) {
        cv::Mat sides;
        cv::hconcat(meshing::RenderCloudPreview(cloud, *labels, *names, meshing::Side::kFront,
                                                preview_options, meshed.stats.bounds)
                        .image,
                    meshing::RenderCloudPreview(cloud, *labels, {}, meshing::Side::kBack,
                                                preview_options, meshed.stats.bounds)
                        .image,
                    sides);
        const fs::path file = out / (std::string("preview-cloud-") + name + ".png");
        WritePng(file, sides);
        written.push_back(file.string());
        progress.Update(++done / 6.0);
      }
      timings["previews"] = SecondsSince(stage_start);
    }

    // Body measurements from the mesh: every value, or the reason it is withheld.
    stage_start = Clock::now();
    progress.Stage("measurements");
    const measurement::SurfaceMesh surface{meshed.mesh.vertices, meshed.mesh.triangles};
    const measurement::BodyMeasurements body = measurement::MeasureBody(surface);
    const nlohmann::json measurements = measurement::ToJson(body);
    WriteJsonFile(out / "measurements.json", measurements);
    written.push_back((out / "measurements.json").string());
    int measured = 0, withheld = 0;
    for (const measurement::Measurement& m : body.measurements)
      ++(m.value_mm ? measured : withheld);
    summary["measurements"] = {{"file", "measurements.json"},
                               {"human", body.human},
                               {"stature_mm", measurements["stature_mm"]},
                               {"measured", measured},
                               {"withheld", withheld}};
    if (!o.no_previews) {
      const fs::path file = out / "preview-measurements.png";
      WritePng(file, measurement::RenderPreview(surface, body, o.preview_height));
      written.push_back(file.string());
    }
    timings["measurements"] = SecondsSince(stage_start);
  } catch (const CommandExit& e) {
    finish(false, e.what());
    // The device shows why its scan gave nothing (not for usage errors: no scan id).
    if (!o.upload.empty() && e.status() == kExitFailure) UploadFailure(o, out, summary);
    throw;
  } catch (const std::exception& e) {
    finish(false, e.what());
    if (!o.upload.empty()) UploadFailure(o, out, summary);
    throw CommandExit(kExitFailure, e.what());
  }
  finish(true, "");
  if (!o.upload.empty()) Upload(o, out, summary);
  if (o.json) {
    std::printf("%s\n", summary.dump(2).c_str());
    return;
  }
  const nlohmann::json& mesh = summary["mesh"];
  std::printf(
      "scan %s: %zu points -> mesh of %d triangles, %d hole(s) (largest %.0f mm round), "
      "%.1f s\n",
      summary["scan_id"].get<std::string>().c_str(),
      summary["reconstruction"].value("points", size_t{0}), mesh["triangles"].get<int>(),
      mesh["holes"]["count"].get<int>(), mesh["holes"]["largest_perimeter_mm"].get<double>(),
      timings["total"].get<double>());
  for (const auto& warning : warnings)
    std::printf("warning: %s\n", warning.get<std::string>().c_str());
  for (const auto& file : written) std::printf("%s\n", file.c_str());
}

}  // namespace

void AddProcessCommand(CLI::App& app) {
  auto options = std::make_shared<ProcessOptions>();
  auto* cmd = app.add_subcommand(
      "process",
      "a scan archive to points, mesh, previews and summary.json in one folder (exit 0 done, "
      "1 no usable result, 2 usage)");
  cmd->add_option("scan", options->scan, "scan archive (.mscan)")->required();
  cmd->add_option("--calibration", options->calibration, "calibration.json")->required();
  cmd->add_option("--out", options->out, "output folder (created)")->required();
  cmd->add_option("--formats", options->formats,
                  "mesh formats, comma-separated: ply, obj, stl (ply always)")
      ->capture_default_str();
  cmd->add_option("--board", options->board, "board.json (the bounding cylinder)");
  cmd->add_flag("--calibration-mismatch-ok", options->calibration_mismatch_ok,
                "process an archive recorded with another calibration (a warning)");
  cmd->add_flag("--no-previews", options->no_previews, "write no preview PNGs");
  cmd->add_option("--preview-height", options->preview_height, "preview height in pixels")
      ->check(CLI::Range(64, 8192))
      ->capture_default_str();
  AddMeshingFlags(cmd, &options->meshing);
  cmd->add_flag("--json", options->json, "print summary.json on stdout");
  cmd->add_option("--upload", options->upload,
                  "put the results (mesh.ply, previews, measurements.json, summary.json) on "
                  "the device at host:port that recorded the scan (exit 3 if it refuses)");
  cmd->add_option("--token", options->token, "the device's bearer token for --upload")
      ->envname(std::string(protocol::kTokenEnvironmentVariable));
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

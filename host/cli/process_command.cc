#include "host/cli/process_command.h"

#include <cstdio>
#include <memory>
#include <string>

#include "common/protocol/protocol.h"
#include "host/cli/exit_status.h"
#include "host/cli/mesh_command.h"
#include "host/cli/progress.h"

namespace mirrorscan::cli {
namespace {

struct ProcessCommandOptions {
  std::string scan, calibration, out, board;
  std::string formats = "ply";
  bool no_previews = false;
  bool json = false;
  pipeline::ProcessOptions process;
};

void Run(ProcessCommandOptions o) {  // a copy: the options are filled in here
  o.process.formats = ParseFormats(o.formats);
  o.process.previews = !o.no_previews;
  const pipeline::ProcessResult result =
      RunProcess(o.scan, o.calibration, o.board, o.out, o.process);
  const nlohmann::json& summary = result.summary;
  if (!result.uploaded.empty()) {
    std::fprintf(stderr, "process: %zu result(s) of %s uploaded to %s\n", result.uploaded.size(),
                 summary["scan_id"].get<std::string>().c_str(), o.process.upload.c_str());
  }
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
      summary["timings_s"]["total"].get<double>());
  for (const auto& warning : summary["warnings"]) {
    std::printf("warning: %s\n", warning.get<std::string>().c_str());
  }
  for (const auto& file : result.written) std::printf("%s\n", file.string().c_str());
}

}  // namespace

pipeline::ProcessResult RunProcess(const std::filesystem::path& archive,
                                   const std::filesystem::path& calibration,
                                   const std::filesystem::path& board,
                                   const std::filesystem::path& out,
                                   pipeline::ProcessOptions options) {
  Progress progress("process");
  std::string stage;
  options.progress = [&](const std::string& name, double fraction) {
    if (name != stage) progress.Stage(stage = name);
    progress.Update(fraction);
  };
  try {
    pipeline::ProcessResult result = pipeline::Process(archive, calibration, board, out, options);
    progress.Done();
    return result;
  } catch (const pipeline::ProcessError& e) {
    progress.Done();
    if (!e.upload_warning().empty()) {
      std::fprintf(stderr, "process: warning: %s\n", e.upload_warning().c_str());
    }
    const bool input = dynamic_cast<const pipeline::InputError*>(&e) != nullptr;
    const bool upload = dynamic_cast<const pipeline::UploadError*>(&e) != nullptr;
    throw CommandExit(input ? kExitUsage : upload ? kExitUpload : kExitFailure, e.what());
  }
}

void AddProcessCommand(CLI::App& app) {
  auto options = std::make_shared<ProcessCommandOptions>();
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
  cmd->add_option("--board", options->board,
                  "board.json (the bounding cylinder; the sweep's end for the pose check)");
  cmd->add_flag("--calibration-mismatch-ok", options->process.calibration_mismatch_ok,
                "process an archive recorded with another calibration (a warning)");
  cmd->add_flag("--no-previews", options->no_previews, "write no preview PNGs");
  cmd->add_option("--preview-height", options->process.preview_height, "preview height in pixels")
      ->check(CLI::Range(64, 8192))
      ->capture_default_str();
  AddMeshingFlags(cmd, &options->process.meshing);
  cmd->add_flag("--json", options->json, "print summary.json on stdout");
  cmd->add_option("--upload", options->process.upload,
                  "put the results (mesh.ply, previews, measurements.json, summary.json) on "
                  "the device at host:port that recorded the scan (exit 3 if it refuses)");
  cmd->add_option("--token", options->process.token, "the device's bearer token for --upload")
      ->envname(std::string(protocol::kTokenEnvironmentVariable));
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli

#include "host/pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <optional>
#include <system_error>
#include <tuple>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/core/version.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/config/calibration.h"
#include "common/config/json_reader.h"
#include "common/mesh/cloud_io.h"
#include "common/mesh/mesh_io.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "host/board/board_json.h"
#include "host/measurement/preview.h"
#include "host/meshing/preview.h"
#include "host/pipeline/upload.h"
#include "host/pose/pose_check.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::pipeline {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Everything Process writes; removed first so a failed run leaves no stale result (least of
// all a mesh from an earlier scan) beside its summary.
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
  if (!out) throw NoResultError("cannot write " + path.string());
}

void WritePng(const fs::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw NoResultError("cannot write " + path.string());
}

// The cameras' names from the archive header, "camera N" where it names none.
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
      present.push_back(reconstruction::PointViewName(static_cast<PointView>(view)));
    }
  }
  if (present.size() < 2) {
    throw NoResultError(
        "the cloud covers " +
        (present.empty() ? std::string("no view") : "only the " + present[0] + " view") + " (" +
        std::to_string(total) +
        " points): a body needs the centre and mirror views; are the mirrors in the "
        "calibration's view regions?");
  }
}

// The checks before any work (no summary.json when they fail).
void CheckInputs(const fs::path& archive, const fs::path& calibration, const fs::path& board,
                 const fs::path& out, const ProcessOptions& options) {
  try {
    options.meshing.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  if (options.preview_height < 64 || options.preview_height > 8192) {
    throw InputError("preview height " + std::to_string(options.preview_height) +
                     " px: must be in [64, 8192]");
  }
  std::error_code error;
  for (const fs::path& file : {archive, calibration, board}) {
    if (!file.empty() && !fs::is_regular_file(file, error)) {
      throw InputError(file.string() + ": no such file");
    }
  }
  if (archive.empty() || calibration.empty()) throw InputError("no archive or no calibration");
  fs::create_directories(out, error);
  if (!fs::is_directory(out, error)) {
    throw InputError(out.string() + ": cannot create the directory");
  }
  for (const char* name : kOutputs) fs::remove(out / name, error);
}

// One run: its inputs, what each stage made and the summary so far.
class Job {
 public:
  Job(fs::path archive, fs::path calibration, fs::path board, fs::path out,
      const ProcessOptions& options)
      : archive_path_(std::move(archive)),
        calibration_path_(std::move(calibration)),
        board_path_(std::move(board)),
        out_(std::move(out)),
        options_(options),
        formats_(CheckMeshFormats(options.formats)) {
    CheckInputs(archive_path_, calibration_path_, board_path_, out_, options_);
    const meshing::MeshingOptions& m = options_.meshing;
    summary_ = {
        {"ok", false},
        {"versions",
         {{"mirrorscan", MIRRORSCAN_VERSION},
          {"open3d", meshing::Open3dVersion()},
          {"embree", meshing::EmbreeVersion()},
          {"opencv", CV_VERSION}}},
        {"inputs",
         {{"archive", FileInput(archive_path_)}, {"calibration", FileInput(calibration_path_)}}},
        {"options",
         {{"formats", formats_},
          {"watertight", m.watertight},
          {"voxel_mm", m.voxel_mm},
          {"cell_mm", m.cell_mm},
          {"depth", m.depth},
          {"threads", m.threads},
          {"trim_distance_mm", m.trim_distance_mm}}},
        {"timings_s", nlohmann::json::object()},
        {"warnings", nlohmann::json::array()},
        // Filled in from host/measurement once the mesh is measured.
        {"measurements", nullptr}};
    if (!board_path_.empty()) summary_["inputs"]["board"] = FileInput(board_path_);
  }

  void Run() {
    ReadInputs();
    Reconstruct();
    Pose();
    Mesh();
    Stage("writing the mesh");
    for (const fs::path& file : WriteMeshFormats(result_.mesh, out_ / "mesh.ply", formats_)) {
      Wrote(file);
    }
    Time("write_mesh");
    if (options_.previews) Previews();
    Measure();
  }

  // Writes summary.json, ok or with the reason it is not.
  void Finish(bool ok, const std::string& reason) {
    summary_["ok"] = ok;
    if (!ok) summary_["reason"] = reason;
    nlohmann::json outputs = nlohmann::json::array();
    for (const fs::path& file : result_.written) outputs.push_back(file.string());
    summary_["outputs"] = outputs;
    summary_["timings_s"]["total"] = SecondsSince(start_);
    WriteJsonFile(out_ / "summary.json", summary_);
  }

  void Upload() {
    result_.uploaded = UploadResults(options_.upload, options_.token, out_, summary_);
  }

  // After a failed run: the failure is what the caller hears, the upload's own trouble only
  // a warning on it.
  void UploadFailure(ProcessError* failure) {
    try {
      Upload();
    } catch (const UploadError& e) {
      failure->set_upload_warning(e.what());
    }
  }

  ProcessResult TakeResult() {
    result_.summary = std::move(summary_);
    return std::move(result_);
  }

 private:
  void Stage(const std::string& name) {
    stage_ = name;
    stage_start_ = Clock::now();
    Progress(0.0);
  }
  void Progress(double fraction) const {
    if (options_.progress) options_.progress(stage_, fraction);
  }
  void Time(const std::string& key) { summary_["timings_s"][key] = SecondsSince(stage_start_); }
  void Wrote(const fs::path& file) { result_.written.push_back(file); }
  void Warn(const std::string& warning) { summary_["warnings"].push_back(warning); }

  void ReadInputs() {
    Stage("reading the archive");
    try {
      archive_ = ReadScanFile(archive_path_);
      calibration_ = Calibration::Load(calibration_path_);
    } catch (const ScanFormatError& e) {
      throw InputError(e.what());
    } catch (const ConfigError& e) {
      throw InputError(e.what());
    }
    const std::string stem = archive_path_.stem().string();
    scan_id_ = archive_.header.is_object() ? archive_.header.value("scan_id", stem) : stem;
    summary_["scan_id"] = scan_id_;
    if (!options_.upload.empty()) CheckUploadTarget(options_.upload, options_.token, scan_id_);
    const ScanReadReport& report = archive_.report;
    summary_["archive"] = {{"complete", report.complete},
                           {"frames", report.frames},
                           {"peaks", report.peaks},
                           {"message", report.message}};
    if (!report.complete) Warn(archive_path_.string() + ": " + report.message);
    Time("read");
  }

  void Reconstruct() {
    Stage("reconstruction");
    reconstruction::ReconstructOptions options;
    if (!board_path_.empty()) {
      try {
        options.cylinder = host_board::BoundingCylinderFromBoard(board_path_);
      } catch (const ConfigError& e) {
        throw InputError(e.what());
      }
    }
    options.allow_calibration_mismatch = options_.calibration_mismatch_ok;
    options.calibration_file_sha256 = summary_["inputs"]["calibration"]["sha256"];
    options.progress = [this](const std::string&, double fraction) { Progress(fraction); };
    reconstruction::Reconstruction reconstruction;
    try {
      reconstruction = reconstruction::Reconstruct(archive_, calibration_, options);
    } catch (const reconstruction::ReconstructError& e) {
      throw NoResultError(e.what());
    }
    header_ = archive_.header;
    archive_ = ScanArchive();  // the frames are not needed any more
    const reconstruction::ReconstructSummary& reconstructed = reconstruction.summary;
    summary_["reconstruction"] = reconstruction::SummaryJson(reconstructed);
    for (const std::string& warning : reconstructed.warnings) Warn(warning);
    Time("reconstruct");
    for (const auto& [name, seconds] : reconstructed.timings_s) {
      summary_["timings_s"]["reconstruct." + name] = seconds;
    }
    cloud_ = std::move(reconstruction.cloud);
    stage_start_ = Clock::now();
    WritePointCloud(out_ / "points.ply", cloud_);
    Wrote(out_ / "points.ply");
    Time("write_points");
    if (cloud_.points.size() < static_cast<size_t>(options_.meshing.min_points)) {
      throw NoResultError("no usable points: " + std::to_string(cloud_.points.size()) +
                          " in the cloud, at least " + std::to_string(options_.meshing.min_points) +
                          " needed for a surface (" + std::to_string(reconstructed.peaks) +
                          " peaks in the archive)");
    }
    CheckViews(reconstructed);
  }

  // How the person stood, from the cloud, against the standard posture: in the summary
  // even when a later stage fails, since a bad stance is often why.
  void Pose() {
    Stage("pose check");
    pose::PoseOptions options;
    std::optional<double> sweep_end, board_mirror_top;
    if (!board_path_.empty()) {
      try {
        const host_board::BoardReach board = host_board::ReachFromBoard(board_path_);
        sweep_end = board.sweep_end_mm;
        board_mirror_top = board.mirror_top_mm;
      } catch (const ConfigError& e) {
        throw InputError(e.what());
      }
    }
    options.reach = pose::ReachOf(calibration_, sweep_end, board_mirror_top);
    result_.pose = pose::CheckPose(cloud_, options);
    summary_["pose"] = pose::ToJson(result_.pose, options);
    Time("pose");
  }

  void Mesh() {
    Stage("Poisson surface");
    meshing::MeshingResult meshed;
    try {
      meshed = meshing::MeshCloud(cloud_, options_.meshing);
    } catch (const meshing::MeshingError& e) {
      throw NoResultError(std::string("no usable mesh: ") + e.what());
    }
    summary_["mesh"] = meshing::SummaryJson(meshed);
    for (const std::string& warning : meshed.warnings) Warn(warning);
    Time("mesh");
    summary_["timings_s"]["mesh.downsample"] = meshed.downsample_s;
    summary_["timings_s"]["mesh.poisson"] = meshed.poisson_s;
    summary_["timings_s"]["mesh.trim"] = meshed.trim_s;
    bounds_ = meshed.stats.bounds;
    result_.mesh = std::move(meshed.mesh);
  }

  // The mesh from four sides, then the cloud by view and by camera (front and back side by
  // side), all framed like the mesh.
  void Previews() {
    Stage("previews");
    meshing::PreviewOptions preview;
    preview.height_px = options_.preview_height;
    preview.title = scan_id_;
    int done = 0;
    for (meshing::Side side : meshing::kAllSides) {
      const fs::path file = out_ / (std::string("preview-") + meshing::SideName(side) + ".png");
      WritePng(file, meshing::RenderMeshPreview(result_.mesh, side, preview).image);
      Wrote(file);
      Progress(++done / 6.0);
    }
    size_t camera_count = 0;
    for (const CloudPoint& point : cloud_.points) {
      camera_count = std::max<size_t>(camera_count, point.camera + 1u);
    }
    const std::vector<std::string> view_names = {"centre", "left mirror", "right mirror",
                                                 "left-right", "right-left"};
    const std::vector<std::string> camera_names = CameraNames(header_, camera_count);
    for (const auto& [name, colour_by, names] :
         {std::tuple{"views", meshing::ColourBy::kView, &view_names},
          {"cameras", meshing::ColourBy::kCamera, &camera_names}}) {
      cv::Mat sides;
      cv::hconcat(
          meshing::RenderCloudPreview(cloud_, colour_by, *names, meshing::Side::kFront, preview,
                                      bounds_)
              .image,
          meshing::RenderCloudPreview(cloud_, colour_by, {}, meshing::Side::kBack, preview, bounds_)
              .image,
          sides);
      const fs::path file = out_ / (std::string("preview-cloud-") + name + ".png");
      WritePng(file, sides);
      Wrote(file);
      Progress(++done / 6.0);
    }
    Time("previews");
  }

  // Body measurements from the mesh: every value, or the reason it is withheld.
  void Measure() {
    Stage("measurements");
    const measurement::BodyMeasurements& body = result_.measurements =
        measurement::MeasureBody(result_.mesh);
    const nlohmann::json measurements = measurement::ToJson(body);
    WriteJsonFile(out_ / "measurements.json", measurements);
    Wrote(out_ / "measurements.json");
    int measured = 0, withheld = 0;
    for (const measurement::Measurement& m : body.measurements)
      ++(m.value_mm ? measured : withheld);
    summary_["measurements"] = {{"file", "measurements.json"},
                                {"human", body.human},
                                {"stature_mm", measurements["stature_mm"]},
                                {"measured", measured},
                                {"withheld", withheld}};
    if (options_.previews) {
      const fs::path file = out_ / "preview-measurements.png";
      WritePng(file, measurement::RenderPreview(result_.mesh, body, options_.preview_height));
      Wrote(file);
    }
    Time("measurements");
  }

  const fs::path archive_path_, calibration_path_, board_path_, out_;
  const ProcessOptions& options_;
  const std::vector<std::string> formats_;
  const Clock::time_point start_ = Clock::now();
  std::string stage_;
  Clock::time_point stage_start_ = start_;
  nlohmann::json summary_;
  ScanArchive archive_;
  Calibration calibration_;
  nlohmann::json header_;
  std::string scan_id_;
  PointCloud cloud_;
  Eigen::AlignedBox3d bounds_;
  ProcessResult result_;
};

}  // namespace

ProcessResult Process(const fs::path& archive, const fs::path& calibration, const fs::path& board,
                      const fs::path& out, const ProcessOptions& options) {
  Job job(archive, calibration, board, out, options);
  try {
    job.Run();
  } catch (ProcessError& e) {
    job.Finish(false, e.what());
    // The device shows why its scan gave nothing (not for bad inputs: no scan id then).
    if (!options.upload.empty() && dynamic_cast<const NoResultError*>(&e)) job.UploadFailure(&e);
    throw;
  } catch (const std::exception& e) {
    NoResultError failure(e.what());
    job.Finish(false, e.what());
    if (!options.upload.empty()) job.UploadFailure(&failure);
    throw failure;
  }
  job.Finish(true, "");
  if (!options.upload.empty()) job.Upload();
  return job.TakeResult();
}

std::vector<std::string> CheckMeshFormats(const std::vector<std::string>& formats) {
  std::vector<std::string> out;
  for (const std::string& format : formats) {
    if (format != "ply" && format != "obj" && format != "stl") {
      throw InputError("formats: \"" + format + "\" is not one of ply, obj, stl");
    }
    if (std::find(out.begin(), out.end(), format) == out.end()) out.push_back(format);
  }
  if (std::find(out.begin(), out.end(), "ply") == out.end()) out.insert(out.begin(), "ply");
  return out;
}

std::vector<fs::path> WriteMeshFormats(const TriangleMesh& mesh, const fs::path& ply_path,
                                       const std::vector<std::string>& formats) {
  std::vector<fs::path> written;
  for (const std::string& format : formats) {
    fs::path file = ply_path;
    file.replace_extension("." + format);
    WriteTriangleMesh(mesh, file);
    written.push_back(file);
  }
  return written;
}

}  // namespace mirrorscan::pipeline

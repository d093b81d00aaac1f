#pragma once
// The host's processing of one scan (docs/meshing.md, "the batch job"): an archive and a
// calibration in, a folder out. Reconstruction (host/reconstruction) -> points.ply -> pose
// check (host/pose, summary.json's "pose") -> Poisson mesh (host/meshing) -> mesh.ply (.obj, .stl)
// -> previews -> measurements (host/measurement) -> summary.json; optionally the results put back
// on the device the scan came from. `mirrorscan process`, `mirrorscan device watch --process` and
// the tests call Process in-process.
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/mesh/triangle_mesh.h"
#include "host/measurement/measure.h"
#include "host/meshing/meshing.h"
#include "host/pose/pose_check.h"

namespace mirrorscan::pipeline {

// Why Process gave no result; the message is one line. When it fails after reading its
// inputs, summary.json says the same ("ok": false, "reason").
class ProcessError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  // A failed run's summary that could not be put on the device (options.upload), or "".
  const std::string& upload_warning() const { return upload_warning_; }
  void set_upload_warning(std::string warning) { upload_warning_ = std::move(warning); }

 private:
  std::string upload_warning_;
};
// A bad input: an option out of range, a missing file, a file that is not an archive, a
// calibration or a board.json (the CLI's exit 2).
class InputError : public ProcessError {
 public:
  using ProcessError::ProcessError;
};
// The scan cannot give a usable result: no usable points, a cloud of one view, no surface,
// an archive made with another calibration, an unreadable archive body (exit 1).
class NoResultError : public ProcessError {
 public:
  using ProcessError::ProcessError;
};
// options.upload: the device could not be reached or refused the results; the folder holds
// what was made (exit 3).
class UploadError : public ProcessError {
 public:
  using ProcessError::ProcessError;
};

struct ProcessOptions {
  // Mesh files besides mesh.ply: any of "ply", "obj", "stl" (ply is always written).
  std::vector<std::string> formats = {"ply"};
  meshing::MeshingOptions meshing;
  // Process an archive recorded with another calibration (a warning, not an error).
  bool calibration_mismatch_ok = false;
  bool previews = true;
  int preview_height = 900;
  // The device (host:port) the archive came from and its bearer token: checked before any
  // work (it answers, has the scan, takes the token), the results put on it at the end, a
  // failed run's summary.json too. Empty: no upload.
  std::string upload;
  std::string token;
  // Progress: a stage's name and how far it is in [0, 1] (0 when it begins). May be empty.
  std::function<void(const std::string& stage, double fraction)> progress;
};

struct ProcessResult {
  nlohmann::json summary;                      // what summary.json holds
  std::vector<std::filesystem::path> written;  // the files written, summary.json aside
  std::vector<std::string> uploaded;           // the results put on the device, in order
  TriangleMesh mesh;                           // mesh.ply's
  measurement::BodyMeasurements measurements;  // measurements.json's
  pose::PoseReport pose;                       // summary.json's "pose"
};

// Processes `archive` with `calibration` (and `board`'s bounding cylinder unless empty)
// into the folder `out` (created; the files a run writes are removed first, so a failed
// run leaves no earlier scan's mesh beside its summary). Throws InputError, NoResultError
// or UploadError; any other failure after the inputs were read is a NoResultError.
ProcessResult Process(const std::filesystem::path& archive,
                      const std::filesystem::path& calibration, const std::filesystem::path& board,
                      const std::filesystem::path& out, const ProcessOptions& options);

// The mesh formats in the order given, each once, "ply" first unless given; InputError
// naming one that is not "ply", "obj" or "stl".
std::vector<std::string> CheckMeshFormats(const std::vector<std::string>& formats);

// Writes the mesh as ply_path with each format's extension; returns the files written.
std::vector<std::filesystem::path> WriteMeshFormats(const TriangleMesh& mesh,
                                                    const std::filesystem::path& ply_path,
                                                    const std::vector<std::string>& formats);

}  // namespace mirrorscan::pipeline

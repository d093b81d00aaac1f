#include "host/reconstruction/archive_check.h"

#include <exception>
#include <string>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

namespace {

// The archive names its calibration by the file's SHA-256 (the device), by content hash,
// or by carrying it whole (the simulator); every one given must match.
void CheckCalibration(const ScanArchive& archive, const Calibration& calibration,
                      const ReconstructOptions& options, ReconstructSummary* summary) {
  std::vector<std::string> mismatches;
  bool named = false;
  if (const auto* sha = HeaderValue(archive.header, "calibration_sha256");
      sha && sha->is_string()) {
    named = true;
    if (!options.calibration_file_sha256.empty() &&
        sha->get<std::string>() != options.calibration_file_sha256) {
      mismatches.push_back("the archive's calibration_sha256 " + sha->get<std::string>() +
                           " is not this file's " + options.calibration_file_sha256);
    }
  }
  if (const auto* hash = HeaderValue(archive.header, "calibration_hash");
      hash && hash->is_string()) {
    named = true;
    if (hash->get<std::string>() != calibration.ContentHash()) {
      mismatches.push_back("the archive's calibration_hash " + hash->get<std::string>() +
                           " is not this calibration's " + calibration.ContentHash());
    }
  }
  if (const auto* embedded = HeaderValue(archive.header, "calibration");
      embedded && embedded->is_object()) {
    named = true;
    std::string hash;
    try {
      hash = Calibration::Parse(*embedded, "the archive's header").ContentHash();
    } catch (const std::exception& e) {
      hash = std::string("unreadable (") + e.what() + ")";
    }
    if (hash != calibration.ContentHash()) {
      mismatches.push_back("the archive was made with calibration " + hash + ", this one is " +
                           calibration.ContentHash());
    }
  }
  if (!named)
    summary->warnings.push_back("the archive does not say which calibration it was made with");
  if (mismatches.empty()) return;
  std::string text = mismatches.front();
  for (size_t i = 1; i < mismatches.size(); ++i) text += "; " + mismatches[i];
  if (!options.allow_calibration_mismatch) {
    throw CalibrationMismatchError("calibration mismatch: " + text +
                                   " (another cabinet or an older calibration; "
                                   "--calibration-mismatch-ok to use it anyway)");
  }
  summary->warnings.push_back("calibration mismatch accepted: " + text);
}

}  // namespace

const nlohmann::json* HeaderValue(const nlohmann::json& header, const char* key) {
  if (!header.is_object()) return nullptr;
  const auto it = header.find(key);
  return it == header.end() ? nullptr : &*it;
}

void CheckArchive(const ScanArchive& archive, const Calibration& calibration,
                  const ReconstructOptions& options, ReconstructSummary* summary) {
  summary->archive_message = archive.report.message;
  summary->archive_complete = archive.report.complete;
  if (archive.header.is_null())
    throw ReconstructError("no readable header (" + archive.report.message + ")");
  if (!archive.report.complete)
    summary->warnings.push_back("incomplete archive, using what was recovered: " +
                                archive.report.message);
  if (calibration.mirrors.size() != 2)
    throw ReconstructError("the calibration needs exactly two mirrors");
  CheckCalibration(archive, calibration, options, summary);
}

std::vector<const CalibrationCamera*> CamerasOf(const ScanArchive& archive,
                                                const Calibration& calibration) {
  std::vector<const CalibrationCamera*> cameras;
  const auto* listed = HeaderValue(archive.header, "cameras");
  if (!listed || !listed->is_array()) {
    for (const CalibrationCamera& c : calibration.cameras) cameras.push_back(&c);
    return cameras;
  }
  for (const nlohmann::json& entry : *listed) {
    const std::string name =
        entry.is_object() && entry.contains("name") && entry["name"].is_string()
            ? entry["name"].get<std::string>()
            : "";
    cameras.push_back(calibration.FindCamera(name));
  }
  // A camera the archive lists but never used does not need calibrating.
  std::vector<bool> used(cameras.size(), false);
  for (const FrameRecord& frame : archive.frames) {
    if (frame.camera >= cameras.size()) {
      throw ReconstructError("frame " + std::to_string(frame.sequence) + " names camera " +
                             std::to_string(frame.camera) + "; the archive lists " +
                             std::to_string(cameras.size()) + " camera(s)");
    }
    used[frame.camera] = true;
  }
  for (size_t i = 0; i < cameras.size(); ++i) {
    if (used[i] && !cameras[i]) {
      throw ReconstructError("the archive's camera \"" +
                             (*listed)[i].value("name", std::string("?")) +
                             "\" is not in the calibration");
    }
  }
  return cameras;
}

std::vector<std::array<const CalibrationView*, 2>> MirrorViewsOf(
    const std::vector<const CalibrationCamera*>& cameras, const Calibration& calibration) {
  std::vector<std::array<const CalibrationView*, 2>> views(cameras.size(), {nullptr, nullptr});
  for (size_t c = 0; c < cameras.size(); ++c) {
    if (!cameras[c]) continue;
    for (int m = 0; m < 2; ++m) {
      for (const CalibrationView& view : cameras[c]->views) {
        if (view.mirror && *view.mirror == calibration.mirrors[m].name) views[c][m] = &view;
      }
      if (!views[c][m]) {
        throw ReconstructError("calibration: camera \"" + cameras[c]->name +
                               "\" has no view for the " + calibration.mirrors[m].name +
                               " mirror, so its image there cannot be told from the subject");
      }
    }
  }
  return views;
}

int LaserCountOf(const ScanArchive& archive, const Calibration& calibration) {
  int count = calibration.lasers ? calibration.lasers->count : 1;
  if (const auto* lasers = HeaderValue(archive.header, "lasers");
      lasers && lasers->is_object() && lasers->contains("count") &&
      (*lasers)["count"].is_number_integer()) {
    count = (*lasers)["count"].get<int>();
  }
  if (count < 1 || count > kMaxLasers)
    throw ReconstructError("the archive says " + std::to_string(count) + " lasers; 1 to " +
                           std::to_string(kMaxLasers) + " are supported");
  return count;
}

}  // namespace mirrorscan::reconstruction

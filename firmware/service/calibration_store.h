#pragma once

// The device's calibration.json (GET/PUT /api/v1/calibration): validated before it is
// stored, written atomically, its SHA-256 reported in the status and put in each scan.

#include <filesystem>
#include <mutex>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace mirrorscan::service {

// Throws ConfigError naming `source` and the key when `calibration` is not a calibration
// the device may store. The one place the schema check lives.
void ValidateCalibration(const nlohmann::json& calibration, const std::string& source);

class CalibrationStore {
 public:
  // `path` is <data-dir>/calibration.json; it need not exist yet. A stored file that no
  // longer validates (say, written by a newer schema) is renamed to
  // calibration.json.invalid and problem() says why: the device then runs uncalibrated,
  // so a new calibration can still be uploaded, and the old file is kept for a person.
  explicit CalibrationStore(std::filesystem::path path);

  // The stored text, nullopt when none is stored.
  std::optional<std::string> Get() const;
  // SHA-256 of the stored text; empty when none is stored.
  std::string Sha256() const;
  // Parses and validates `text` (ConfigError naming `source` and the key; nothing is
  // written then), then replaces the stored file atomically (temp, fsync, rename, fsync
  // the directory). Returns the new SHA-256. I/O errors are std::runtime_error.
  std::string Put(const std::string& text, const std::string& source);

  const std::filesystem::path& path() const { return path_; }
  // Why the file found at start was set aside; empty when it was valid or absent, and
  // once a new calibration is stored.
  std::string problem() const;

 private:
  std::filesystem::path path_;
  mutable std::mutex mutex_;
  std::optional<std::string> text_;
  std::string sha256_;
  std::string problem_;
};

}  // namespace mirrorscan::service

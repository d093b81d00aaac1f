#pragma once
// The results of a processed scan put back on the device that recorded it
// (PUT /api/v1/scans/{id}/results/{name}, docs/cli-device.md).
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace mirrorscan::pipeline {

// Before the minutes of processing: the device at `device` (host:port) answers, has the
// scan `scan_id` and takes the token (on a board with open reads a wrong token shows only at
// the upload). UploadError otherwise.
void CheckUploadTarget(const std::string& device, const std::string& token,
                       const std::string& scan_id);

// Puts the folder's results on the device: every file of protocol::ResultKinds in `out`,
// summary.json last (the device's page takes a summary as "processed"); a failed run's
// (summary "ok": false) summary.json alone, the reason. Returns the names put; UploadError
// when the device refuses one or cannot be reached.
std::vector<std::string> UploadResults(const std::string& device, const std::string& token,
                                       const std::filesystem::path& out,
                                       const nlohmann::json& summary);

}  // namespace mirrorscan::pipeline

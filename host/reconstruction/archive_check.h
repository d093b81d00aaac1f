#pragma once
// The archive against the calibration, before anything is computed (docs/reconstruction.md,
// "Errors"): a readable header, the calibration it was made with, and the cameras, mirror
// views and lasers it needs.
#include <array>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config/calibration.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// Lasers a reconstruction can tell apart (views × lasers keys fit a uint16_t's bits).
constexpr int kMaxLasers = 3;

// The header's value at key, or null when the header is no object or lacks it.
const nlohmann::json* HeaderValue(const nlohmann::json& header, const char* key);

// A readable header and two mirrors; the archive's calibration (the device's file SHA-256,
// the content hash, or an embedded calibration) against the given one. Throws
// ReconstructError, or CalibrationMismatchError unless options allow it (then a warning);
// an incomplete archive or one that names no calibration is a warning.
void CheckArchive(const ScanArchive& archive, const Calibration& calibration,
                  const ReconstructOptions& options, ReconstructSummary* summary);

// The archive's cameras by FrameRecord::camera, matched to the calibration's by name; null
// for a listed camera that took no frame and is not calibrated. ReconstructError for a frame
// naming a camera the archive does not list or one the calibration lacks.
std::vector<const CalibrationCamera*> CamerasOf(const ScanArchive& archive,
                                                const Calibration& calibration);

// Per camera: the region of each mirror. A camera without a region for a mirror would
// take that mirror's image for the subject itself (ReconstructError).
std::vector<std::array<const CalibrationView*, 2>> MirrorViewsOf(
    const std::vector<const CalibrationCamera*>& cameras, const Calibration& calibration);

// The header's laser count (else the calibration's, else 1); ReconstructError beyond
// kMaxLasers.
int LaserCountOf(const ScanArchive& archive, const Calibration& calibration);

}  // namespace mirrorscan::reconstruction

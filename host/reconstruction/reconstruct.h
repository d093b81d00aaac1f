#pragma once
// Reconstruction (docs/reconstruction.md): every laser peak of a scan archive to a 3D point
// in the world frame through the calibrated cameras and mirrors. Laser heights per frame
// come from the lines on the panels (host/calibration/laser_height), the slide readback
// checks them and stands in where the panels are not seen. Each peak gets its view (the
// calibration's view regions, mirror rays reflected, rays that bounce in both mirrors
// followed through both) and its laser (bounding cylinder, column counting, then a
// majority vote over peaks that are neighbours in column and frame); then confidence,
// filters, normals from the (column, frame) grid and the merged cloud of every camera and
// view. Each stage is a file of this folder (docs/reconstruction.md names them).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/config/calibration.h"
#include "common/mesh/point_cloud.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/bounding_cylinder.h"
#include "host/reconstruction/options.h"
#include "host/reconstruction/summary.h"

namespace mirrorscan::reconstruction {

// Bad input that makes a cloud impossible or untrustworthy (no header, no frames, a camera
// the calibration lacks, ...). The message is one line saying what is wrong.
class ReconstructError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The archive was made with another calibration than the one given.
class CalibrationMismatchError : public ReconstructError {
 public:
  using ReconstructError::ReconstructError;
};

// The cloud's types are the project's one point cloud (common/mesh/point_cloud.h).
using mirrorscan::CloudPoint;
using mirrorscan::DecidedBy;
using mirrorscan::PointCloud;
using mirrorscan::PointView;
const char* PointViewName(PointView view);
const char* DecidedByName(DecidedBy rule);

struct Reconstruction {
  PointCloud cloud;
  ReconstructSummary summary;
};

// The archive's frames (lasers on) to a cloud. Throws std::invalid_argument for options out
// of range (ReconstructOptions::Validate), CalibrationMismatchError,
// ReconstructError (no header, no frames with peaks, a camera or view the archive needs
// that the calibration lacks, no laser heights at all).
Reconstruction Reconstruct(const ScanArchive& archive, const Calibration& calibration,
                           const ReconstructOptions& options = {});

}  // namespace mirrorscan::reconstruction

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

// The view a point was seen in: directly, in one mirror, or through both mirrors (the
// first named mirror met first). Values as in the virtual cabinet's truth.
enum class PointView : uint8_t {
  kCenter = 0,
  kLeft = 1,
  kRight = 2,
  kLeftRight = 3,
  kRightLeft = 4
};
const char* PointViewName(PointView view);

// Which correspondence rule gave a point its view and laser (docs/reconstruction.md).
enum class DecidedBy : uint8_t {
  kCylinder = 0,
  kVolume = 1,
  kColumnCount = 2,
  kLabelVote = 3,
  kStereo = 4
};
const char* DecidedByName(DecidedBy rule);

struct CloudPoint {
  Eigen::Vector3f point_in_world = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();  // unit, towards the (mirrored) camera
  uint8_t camera = 0;                                // FrameRecord::camera
  PointView view = PointView::kCenter;
  uint8_t laser = 0;
  uint32_t frame = 0;    // the frame's sequence number (FrameRecord::sequence)
  float u = 0;           // image column of the peak
  float v = 0;           // sub-pixel row of the peak
  float confidence = 0;  // in [0, 1]
  DecidedBy rule = DecidedBy::kCylinder;
};

struct PointCloud {
  std::vector<CloudPoint> points;
};

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

// Binary little-endian PLY: x y z nx ny nz (float), camera view laser (uchar), frame
// (uint), u v confidence (float), rule (uchar, DecidedBy). Throws std::runtime_error naming the
// file.
void WritePly(const std::filesystem::path& path, const PointCloud& cloud);
// Reads what WritePly writes (property order as written).
PointCloud ReadPly(const std::filesystem::path& path);

}  // namespace mirrorscan::reconstruction

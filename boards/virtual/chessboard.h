// A printed chessboard held in front of a camera, as for a lens (intrinsics) calibration:
// a flat board of (columns + 1) x (rows + 1) squares with a white margin, rendered by
// exact area coverage like the calibration target, so its corners are alias-free.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/mesh.h"
#include "common/config/json_reader.h"
#include "common/geometry/camera.h"

namespace mirrorscan::virtual_cabinet {

inline constexpr double kChessboardBlackAlbedo = 0.05;
inline constexpr double kChessboardWhiteAlbedo = 0.85;

// The scene file's "chessboard" object. The board faces -y (the camera) at rotation 0,
// its rows along +x and columns along +z; rotation_deg turns it as R = Rz * Ry * Rx.
struct ChessboardConfig {
  int inner_columns = 9;  // inner corners along the board's width (OpenCV's pattern size)
  int inner_rows = 6;
  double square_mm = 30.0;
  double margin_mm = 30.0;  // white border beyond the outer squares
  Eigen::Vector3d center_mm{0.0, -1000.0, 1300.0};
  Eigen::Matrix3d board_to_world = Eigen::Matrix3d::Identity();  // from rotation_deg

  // Keys inner_corners [columns, rows], square_mm, margin_mm, center_mm [x, y, z],
  // rotation_deg [rx, ry, rz]; errors are ConfigErrors naming the key.
  static ChessboardConfig Parse(const JsonReader& reader);
};

class Chessboard {
 public:
  explicit Chessboard(const ChessboardConfig& config);

  const ChessboardConfig& config() const { return config_; }
  Eigen::Vector3d right() const { return config_.board_to_world.col(0); }
  Eigen::Vector3d up() const { return config_.board_to_world.col(2); }
  Eigen::Vector3d front() const { return -config_.board_to_world.col(1); }  // towards -y at 0

  // The board as one flat quad (seen from either side by the renderer).
  TriangleMesh Mesh() const;
  // Mean reflectance over a square footprint of side footprint_mm in the board plane, from
  // the exact black area; nullopt when the point is not on the board.
  std::optional<double> AlbedoArea(const Eigen::Vector3d& point_in_world,
                                   double footprint_mm) const;
  // Inner corners in world, row by row from the top-left as seen from the front (the order
  // cv::findChessboardCorners reports for an upright board).
  std::vector<Eigen::Vector3d> InnerCorners() const;

 private:
  // Board coordinates (u right, v up) in mm from the centre.
  Eigen::Vector2d Local(const Eigen::Vector3d& point_in_world) const;
  double BlackArea(double u0, double u1, double v0, double v1) const;

  ChessboardConfig config_;
  double half_width_ = 0.0, half_height_ = 0.0;  // of the squares, without margin
};

// The poses an operator holds the board in for a lens calibration of `camera`: centred on
// a 3 x 3 grid over the image (pulled in until the whole board shows, so its corners reach
// the image's edges and corners), tilted by `tilt_deg` towards the image centre, plus
// three at the centre (frontal, pitched, turned), in three rounds of tilt and distance
// about `distance_mm` from the camera centre.
std::vector<ChessboardConfig> LensCalibrationPoses(const Camera& camera,
                                                   const ChessboardConfig& board,
                                                   double distance_mm, double tilt_deg = 25.0);

}  // namespace mirrorscan::virtual_cabinet

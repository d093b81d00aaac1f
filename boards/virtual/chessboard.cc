#include "boards/virtual/chessboard.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>

#include <Eigen/Geometry>
#include <optional>

namespace mirrorscan::virtual_cabinet {
namespace {

double Overlap(double a0, double a1, double b0, double b1) {
  return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
}

// A point counts as on the board within this distance of its plane.
constexpr double kSurfaceToleranceMm = 0.5;

}  // namespace

ChessboardConfig ChessboardConfig::Parse(const JsonReader& reader) {
  reader.AllowOnly({"inner_corners", "square_mm", "margin_mm", "center_mm", "rotation_deg"});
  ChessboardConfig c;
  const auto corners = reader.Numbers("inner_corners", 2, std::vector<double>{9.0, 6.0});
  for (double n : corners) {
    if (n < 2 || n > 40 || n != std::floor(n)) {
      reader.Fail("inner_corners", "each must be a whole number in [2, 40]");
    }
  }
  c.inner_columns = static_cast<int>(corners[0]);
  c.inner_rows = static_cast<int>(corners[1]);
  c.square_mm = reader.Number("square_mm", c.square_mm, 1.0, 500.0);
  c.margin_mm = reader.Number("margin_mm", c.margin_mm, 0.0, 500.0);
  const auto center = reader.Numbers(
      "center_mm", 3, std::vector<double>{c.center_mm.x(), c.center_mm.y(), c.center_mm.z()});
  c.center_mm = {center[0], center[1], center[2]};
  const auto angles = reader.Numbers("rotation_deg", 3, std::vector<double>{0.0, 0.0, 0.0});
  constexpr double kDeg = std::numbers::pi / 180.0;
  c.board_to_world = (Eigen::AngleAxisd(angles[2] * kDeg, Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(angles[1] * kDeg, Eigen::Vector3d::UnitY()) *
                      Eigen::AngleAxisd(angles[0] * kDeg, Eigen::Vector3d::UnitX()))
                         .toRotationMatrix();
  return c;
}

Chessboard::Chessboard(const ChessboardConfig& config)
    : config_(config),
      half_width_(0.5 * (config.inner_columns + 1) * config.square_mm),
      half_height_(0.5 * (config.inner_rows + 1) * config.square_mm) {}

Eigen::Vector2d Chessboard::Local(const Eigen::Vector3d& point_in_world) const {
  const Eigen::Vector3d d = point_in_world - config_.center_mm;
  return {right().dot(d), up().dot(d)};
}

TriangleMesh Chessboard::Mesh() const {
  const double w = half_width_ + config_.margin_mm, h = half_height_ + config_.margin_mm;
  const Eigen::Vector3d c = config_.center_mm;
  TriangleMesh mesh;
  mesh.vertices = {c - w * right() - h * up(), c + w * right() - h * up(),
                   c + w * right() + h * up(), c - w * right() + h * up()};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

double Chessboard::BlackArea(double u0, double u1, double v0, double v1) const {
  const double s = config_.square_mm;
  const int columns = config_.inner_columns + 1, rows = config_.inner_rows + 1;
  const int i0 = std::max(0, static_cast<int>(std::floor((u0 + half_width_) / s)));
  const int i1 = std::min(columns - 1, static_cast<int>(std::floor((u1 + half_width_) / s)));
  const int j0 = std::max(0, static_cast<int>(std::floor((half_height_ - v1) / s)));
  const int j1 = std::min(rows - 1, static_cast<int>(std::floor((half_height_ - v0) / s)));
  double area = 0.0;
  for (int j = j0; j <= j1; ++j) {
    const double top = half_height_ - j * s;
    const double dv = Overlap(v0, v1, top - s, top);
    if (dv <= 0.0) continue;
    for (int i = i0; i <= i1; ++i) {
      // The top-left square is black, as on OpenCV's printed pattern.
      if ((i + j) % 2 != 0) continue;
      const double left = -half_width_ + i * s;
      area += dv * Overlap(u0, u1, left, left + s);
    }
  }
  return area;
}

std::optional<double> Chessboard::AlbedoArea(const Eigen::Vector3d& point_in_world,
                                             double footprint_mm) const {
  if (std::abs(front().dot(point_in_world - config_.center_mm)) > kSurfaceToleranceMm) {
    return std::nullopt;
  }
  const Eigen::Vector2d uv = Local(point_in_world);
  const double w = half_width_ + config_.margin_mm, h = half_height_ + config_.margin_mm;
  if (std::abs(uv.x()) > w || std::abs(uv.y()) > h) return std::nullopt;
  const double half = 0.5 * std::max(footprint_mm, 1e-6);
  const double u0 = std::max(uv.x() - half, -w), u1 = std::min(uv.x() + half, w);
  const double v0 = std::max(uv.y() - half, -h), v1 = std::min(uv.y() + half, h);
  const double area = (u1 - u0) * (v1 - v0);
  if (!(area > 1e-12)) return kChessboardWhiteAlbedo;
  const double black = std::clamp(BlackArea(u0, u1, v0, v1) / area, 0.0, 1.0);
  return kChessboardWhiteAlbedo + (kChessboardBlackAlbedo - kChessboardWhiteAlbedo) * black;
}

std::vector<Eigen::Vector3d> Chessboard::InnerCorners() const {
  std::vector<Eigen::Vector3d> corners;
  const double s = config_.square_mm;
  for (int r = 0; r < config_.inner_rows; ++r) {
    for (int c = 0; c < config_.inner_columns; ++c) {
      const double u = -half_width_ + (c + 1) * s, v = half_height_ - (r + 1) * s;
      corners.push_back(config_.center_mm + u * right() + v * up());
    }
  }
  return corners;
}

namespace {

// The board centred on the ray through `pixel`, square to the camera (its rows along the
// image's rows), then turned by pitch (about its horizontal axis) and yaw (about its
// vertical one).
ChessboardConfig PoseAt(const Camera& camera, const ChessboardConfig& board,
                        const Eigen::Vector2d& pixel, double distance_mm, double pitch,
                        double yaw) {
  ChessboardConfig pose = board;
  const auto ray = camera.RayThroughPixel(pixel);
  if (!ray) return pose;
  pose.center_mm = ray->origin + distance_mm * ray->direction;
  const Eigen::Vector3d front = -ray->direction;
  const Eigen::Vector3d image_x =
      camera.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d right = (image_x - image_x.dot(front) * front).normalized();
  const Eigen::Vector3d up = front.cross(right);
  Eigen::Matrix3d facing;
  facing.col(0) = right;
  facing.col(1) = -front;
  facing.col(2) = up;
  pose.board_to_world = facing * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
                        Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
  return pose;
}

// The image bounding box of the pattern and a quarter square of white beyond it (what a
// chessboard detector needs to see to find every corner); nullopt if any of it is behind
// the camera.
std::optional<Eigen::AlignedBox2d> PatternBox(const Camera& camera, const ChessboardConfig& pose) {
  const Chessboard board(pose);
  const double beyond = 0.25 * pose.square_mm;
  const double w = 0.5 * (pose.inner_columns + 1) * pose.square_mm + beyond;
  const double h = 0.5 * (pose.inner_rows + 1) * pose.square_mm + beyond;
  Eigen::AlignedBox2d box;
  for (int i = 0; i <= 8; ++i) {
    for (int j = 0; j <= 8; ++j) {
      if (i != 0 && i != 8 && j != 0 && j != 8) continue;
      const Eigen::Vector3d p = pose.center_mm + (-w + 2 * w * i / 8.0) * board.right() +
                                (-h + 2 * h * j / 8.0) * board.up();
      const auto pixel = camera.ProjectWorld(p);
      if (!pixel) return std::nullopt;
      box.extend(*pixel);
    }
  }
  return box;
}

}  // namespace

std::vector<ChessboardConfig> LensCalibrationPoses(const Camera& camera,
                                                   const ChessboardConfig& board,
                                                   double distance_mm, double tilt_deg) {
  const double tilt = tilt_deg * std::numbers::pi / 180.0;
  const CameraIntrinsics& k = camera.intrinsics;
  const Eigen::Vector2d centre((k.width - 1) / 2.0, (k.height - 1) / 2.0);
  constexpr double kEdgeGapPx = 3.0;
  std::vector<ChessboardConfig> poses;
  // Three rounds over the grid: leaning towards the image centre at the given distance,
  // away from it and more a fifth nearer, and towards it most a quarter further (its
  // smaller squares reach nearest the image's edges). Tilt and distance together pin the
  // focal length (one tilt at one distance left it 0.07 % off).
  constexpr std::array<std::pair<double, double>, 3> kRounds = {
      {{1.0, 1.0}, {-1.4, 0.8}, {1.6, 1.25}}};  // tilt factor, distance factor
  for (const auto& [tilt_factor, distance_factor] : kRounds) {
    const double sign = tilt_factor;
    const double distance = distance_factor * distance_mm;
    for (int gy = -1; gy <= 1; ++gy) {
      for (int gx = -1; gx <= 1; ++gx) {
        const double pitch = sign * (gy != 0 ? -gy * tilt : tilt);
        const double yaw = sign * (gx != 0 ? gx * tilt : -tilt);
        // Slide the board until its image touches the edges of its grid place (a corner, an
        // edge's middle, the centre), so the corners reach as far out as they can.
        Eigen::Vector2d target = centre;
        ChessboardConfig pose = PoseAt(camera, board, target, distance, pitch, yaw);
        for (int step = 0; step < 30; ++step) {
          const auto box = PatternBox(camera, pose);
          if (!box) break;
          Eigen::Vector2d shift = Eigen::Vector2d::Zero();
          const Eigen::Vector2d low(-0.5 + kEdgeGapPx, -0.5 + kEdgeGapPx);
          const Eigen::Vector2d high(k.width - 0.5 - kEdgeGapPx, k.height - 0.5 - kEdgeGapPx);
          for (int axis = 0; axis < 2; ++axis) {
            const int g = axis == 0 ? gx : gy;
            if (g < 0) shift[axis] = low[axis] - box->min()[axis];
            if (g > 0) shift[axis] = high[axis] - box->max()[axis];
            if (g == 0) shift[axis] = centre[axis] - box->center()[axis];
          }
          target += 0.8 * shift;
          pose = PoseAt(camera, board, target, distance, pitch, yaw);
        }
        poses.push_back(pose);
      }
    }
  }
  for (const auto& [pitch, yaw] : {std::pair{0.0, 0.0}, {1.4 * tilt, 0.0}, {0.0, 1.4 * tilt}}) {
    poses.push_back(PoseAt(camera, board, centre, distance_mm, pitch, yaw));
  }
  return poses;
}

}  // namespace mirrorscan::virtual_cabinet

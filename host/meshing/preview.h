#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "host/meshing/meshing.h"

namespace mirrorscan::meshing {

// Where a preview looks from, in the world frame (the camera stands at -y): front looks
// along +y, back along -y, left from -x (the body's right side), right from +x.
enum class Side { kFront, kBack, kLeft, kRight };
const char* SideName(Side side);
constexpr std::array<Side, 4> kAllSides = {Side::kFront, Side::kBack, Side::kLeft, Side::kRight};

struct PreviewOptions {
  int height_px = 900;
  std::string title;  // e.g. the scan id, written in the corner
};

// An orthographic view: pixel (column, row) of a world point.
struct PreviewProjection {
  Eigen::Vector3d right, up, forward;  // unit image axes in the world and the view direction
  Eigen::Vector3d origin;              // world point at pixel (0, 0)
  double mm_per_px = 1.0;
  Eigen::Vector2d Pixel(const Eigen::Vector3d& point_in_world) const;
};

struct PreviewImage {
  cv::Mat image;  // CV_8UC3, BGR
  PreviewProjection projection;
};

// The same framing for every side of one body: the bounding box's vertical extent and its
// largest horizontal radius about its centre, with a margin.
PreviewProjection FrameView(const Eigen::AlignedBox3d& bounds, Side side, int height_px);

// The mesh shaded (Embree ray casting, orthographic), with a scale bar and the title.
PreviewImage RenderMeshPreview(const TriangleMesh& mesh, Side side, const PreviewOptions& options);

// What colours a cloud's point: the view or the camera that saw it.
enum class ColourBy { kView, kCamera };

// Points drawn as dots (OpenCV, far ones first) coloured by their view or camera, shaded by
// how their normal faces the viewer, with a legend of label_names (the views' or cameras'
// names in order; none: no legend).
PreviewImage RenderCloudPreview(const PointCloud& cloud, ColourBy colour_by,
                                const std::vector<std::string>& label_names, Side side,
                                const PreviewOptions& options,
                                std::optional<Eigen::AlignedBox3d> bounds = std::nullopt);

// The Embree version previews were built against.
std::string EmbreeVersion();

// The background colour previews leave where nothing is drawn (BGR).
cv::Vec3b PreviewBackground();

}  // namespace mirrorscan::meshing

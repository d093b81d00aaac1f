// Finds the three-panel target's ArUco markers in the centre view and both mirror views
// of one camera image, with corners refined to a few hundredths of a pixel.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace mirrorscan::calibration {

// The camera's three views; target panel i is seen in view i (panel 0 faces the camera,
// panel 1 is seen in the left mirror, panel 2 in the right).
enum class ViewId { kCenter = 0, kLeft = 1, kRight = 2 };
inline constexpr int kViews = 3;
const char* ViewName(ViewId view);

struct DetectedMarker {
  int id = 0;
  // Target corner order (top-left, top-right, bottom-right, bottom-left of the marker as
  // seen from the panel's front), in pixels of the original, unflipped image.
  std::array<Eigen::Vector2d, 4> corners;
  double contrast_dn = 0.0;    // mean step from black border to white surround
  double edge_sigma_px = 0.0;  // mean Gaussian width of the border edges (blur)
  // Sub-pixel points on edge e (from corner e to corner e + 1), away from the corners;
  // the calibration fits the projected edges to them, which lens distortion's bending of
  // the edges does not bias as it does the straight-line corners.
  std::array<std::vector<Eigen::Vector2d>, 4> edge_points;
};

struct ViewDetections {
  std::vector<DetectedMarker> markers;  // sorted by id
  int rejected = 0;  // decoded with this view's ids but not where the panel's layout puts them
};

struct MarkerDetectorOptions {
  int markers_per_panel = 16;
  // Layout of the markers on their panel in panel coordinates (mm), indexed by id; used
  // to reject misread markers (a homography of the panel must carry them to the image).
  std::vector<std::array<Eigen::Vector2d, 4>> layout_mm;
  double layout_tolerance_px = 12.0;  // lens distortion bends a panel's image by a few px
};

// Centre-view markers are read in the image as it is; mirror views are mirror-imaged, so
// they are read in the flipped image and their corners mapped back. A marker counts for
// the view of its panel only, and only when it sits where its panel's layout says.
std::array<ViewDetections, kViews> DetectTargetMarkers(const cv::Mat& gray,
                                                       const MarkerDetectorOptions& options);

// Refines a marker's corners from its black border: points on each of the four edges at
// the centroid of the intensity gradient across it, a line fitted per edge, corners where
// lines meet (a blurred corner's own neighbourhood is biased inwards). nullopt when an
// edge is too short, too faint or leaves the image.
std::optional<DetectedMarker> RefineMarkerCorners(const cv::Mat& gray,
                                                  const DetectedMarker& marker);

}  // namespace mirrorscan::calibration

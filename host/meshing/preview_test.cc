#include "host/meshing/preview.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "host/meshing/test_clouds.h"

namespace mirrorscan::meshing {
namespace {

cv::Mat Foreground(const cv::Mat& image) {
  cv::Mat mask;
  cv::inRange(image, PreviewBackground(), PreviewBackground(), mask);
  cv::bitwise_not(mask, mask);
  return mask;
}

// The body's silhouette in a preview matches where the true surface projects: every
// true vertex lands on a drawn pixel and the drawn region's extent is the surface's.
void ExpectBodyWhereItIs(const PreviewImage& preview, const std::vector<Eigen::Vector3d>& truth,
                         double min_drawn_share, const char* what) {
  cv::Mat foreground = Foreground(preview.image);
  // The annotations (title, scale bar, legend) are ink too; look at the body's band only.
  Eigen::AlignedBox2d projected;
  int on_body = 0;
  for (const Eigen::Vector3d& v : truth) {
    const Eigen::Vector2d pixel = preview.projection.Pixel(v);
    projected.extend(pixel);
    // Within a pixel of a drawn one: a vertex on the silhouette lies half a pixel from the
    // nearest pixel centre the body covers.
    const int col = std::clamp(static_cast<int>(pixel.x()), 1, foreground.cols - 2);
    const int row = std::clamp(static_cast<int>(pixel.y()), 1, foreground.rows - 2);
    on_body += cv::countNonZero(foreground(cv::Rect(col - 1, row - 1, 3, 3))) > 0 ? 1 : 0;
  }
  EXPECT_GT(on_body, 0.97 * truth.size()) << what;
  // Nothing drawn beside the body (beyond 3 px of its projected extent) between the
  // title and the scale bar.
  const int top = static_cast<int>(projected.min().y()) - 3;
  const int bottom = static_cast<int>(projected.max().y()) + 3;
  int stray = 0, drawn = 0;
  for (int row = std::max(top, 45); row < std::min(bottom, foreground.rows - 45); ++row) {
    for (int col = 0; col < foreground.cols; ++col) {
      if (!foreground.at<uint8_t>(row, col)) continue;
      ++drawn;
      if (col < projected.min().x() - 3 || col > projected.max().x() + 3) ++stray;
    }
  }
  EXPECT_EQ(stray, 0) << what;
  EXPECT_GT(drawn, min_drawn_share * foreground.total()) << what;
  EXPECT_LT(drawn, 0.7 * foreground.total()) << what;
}

TEST(MeshPreview, ShowsTheBodyWhereItIs) {
  const TriangleMesh truth = testing_clouds::MannequinSurface();
  PreviewOptions options;
  options.height_px = 600;
  options.title = "test-scan";
  for (Side side : kAllSides) {
    const PreviewImage preview = RenderMeshPreview(truth, side, options);
    ASSERT_EQ(preview.image.rows, 600);
    ExpectBodyWhereItIs(preview, truth.vertices, 0.05, SideName(side));
    // Shaded, not a flat silhouette.
    cv::Scalar mean, stddev;
    cv::meanStdDev(preview.image, mean, stddev, Foreground(preview.image));
    EXPECT_GT(stddev[1], 10.0) << SideName(side);
  }
}

TEST(MeshPreview, FrontAndBackAreMirrorImages) {
  const TriangleMesh truth = testing_clouds::MannequinSurface();
  PreviewOptions options;
  options.height_px = 400;
  cv::Mat front = Foreground(RenderMeshPreview(truth, Side::kFront, options).image);
  cv::Mat back = Foreground(RenderMeshPreview(truth, Side::kBack, options).image);
  const cv::Rect body(0, 40, front.cols, front.rows - 80);  // without the annotations
  cv::Mat flipped;
  cv::flip(back(body), flipped, 1);
  cv::Mat differ;
  cv::bitwise_xor(front(body), flipped, differ);
  EXPECT_LT(cv::countNonZero(differ), 0.02 * cv::countNonZero(front(body)));
}

TEST(CloudPreview, ShowsEachViewInItsColour) {
  const testing_clouds::TruthCloud truth = testing_clouds::MannequinTruthCloud(0.0, 2);
  PreviewOptions options;
  options.height_px = 600;
  // Without a legend, which may overlap the body's band.
  const PreviewImage front =
      RenderCloudPreview(truth.cloud, ColourBy::kView, {}, Side::kFront, options);
  ExpectBodyWhereItIs(front, truth.exact_points, 0.03, "cloud front");
  // Each view's points in a colour of their own: where only the left mirror sees the body
  // (surface facing back-left) the colour differs from where only the right one does.
  const PreviewImage back =
      RenderCloudPreview(truth.cloud, ColourBy::kView, {}, Side::kBack, options);
  cv::Vec3d left_colour(0, 0, 0), right_colour(0, 0, 0);
  int left_count = 0, right_count = 0;
  for (const CloudPoint& point : truth.cloud.points) {
    const Eigen::Vector3d n = point.normal.cast<double>();
    const double towards_mirror = std::abs(n.x()) * std::sqrt(3.0) / 2 + n.y() / 2;
    const bool left = point.view == PointView::kLeft;
    if (point.view == PointView::kCenter || towards_mirror < 0.95 || (n.x() < 0) != left) continue;
    const Eigen::Vector2d pixel = back.projection.Pixel(point.point_in_world.cast<double>());
    const cv::Vec3b bgr =
        back.image.at<cv::Vec3b>(static_cast<int>(pixel.y()), static_cast<int>(pixel.x()));
    (left ? left_colour : right_colour) += cv::Vec3d(bgr[0], bgr[1], bgr[2]);
    ++(left ? left_count : right_count);
  }
  ASSERT_GT(left_count, 100);
  ASSERT_GT(right_count, 100);
  EXPECT_GT(cv::norm(left_colour / left_count - right_colour / right_count), 60.0);
}

TEST(Preview, RefusesEmptyInput) {
  EXPECT_THROW(RenderMeshPreview(TriangleMesh{}, Side::kFront, {}), std::invalid_argument);
  EXPECT_THROW(RenderCloudPreview(PointCloud{}, ColourBy::kView, {}, Side::kFront, {}),
               std::invalid_argument);
}

}  // namespace
}  // namespace mirrorscan::meshing

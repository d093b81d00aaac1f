#include "boards/virtual/rendered_target.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>

#include "common/target/target_test_util.h"

namespace mirrorscan::virtual_cabinet {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

using target_test::Configs;
using target_test::PanelUv;
using target_test::RotatedConfig;

Vector3d PanelPoint(const TargetPanel& p, double u, double v) {
  return p.origin + u * p.right + v * p.up;
}

// The expected module colours, straight from OpenCV's own drawing of each marker.
cv::Mat DrawModules(int id) {
  cv::Mat img;
  cv::aruco::drawMarker(cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), id, 6, img, 1);
  return img;
}

TEST(RenderedTargetTest, AlbedoAtModuleCentresMatchesTheDictionary) {
  for (const TargetConfig& config : Configs()) {
    const RenderedTarget target(config);
    for (const TargetMarker& m : target.markers()) {
      const cv::Mat modules = DrawModules(m.id);
      ASSERT_EQ(modules.rows, 6);
      const Vector3d& tl = m.corners[0];
      const Vector3d along_row = (m.corners[1] - tl) / 6.0;
      const Vector3d down = (m.corners[3] - tl) / 6.0;
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) {
          const Vector3d x = tl + (c + 0.5) * along_row + (r + 0.5) * down;
          const std::optional<double> albedo = target.Albedo(x);
          ASSERT_TRUE(albedo.has_value());
          const double expected = modules.at<unsigned char>(r, c) == 0 ? 0.05 : 0.85;
          EXPECT_DOUBLE_EQ(*albedo, expected) << "id " << m.id << " module " << r << "," << c;
        }
      }
      // The quiet zone just outside each corner is white.
      const Vector3d centre = 0.25 * (m.corners[0] + m.corners[1] + m.corners[2] + m.corners[3]);
      for (const Vector3d& corner : m.corners) {
        const Vector3d outside = corner + 0.5 * config.marker_size_mm / 6.0 *
                                              (corner - centre).normalized() * std::sqrt(2.0);
        EXPECT_DOUBLE_EQ(target.Albedo(outside).value_or(-1.0), 0.85) << m.id;
      }
    }
  }
}

TEST(RenderedTargetTest, AlbedoIsOnlyDefinedOnFrontFaces) {
  const RenderedTarget target(TargetConfig{});
  const TargetPanel& p = target.panels()[0];
  const Vector3d on = PanelPoint(p, 5.0, 5.0);  // white margin
  EXPECT_DOUBLE_EQ(target.Albedo(on).value_or(-1.0), 0.85);
  EXPECT_TRUE(target.Albedo(on + 0.3 * p.normal).has_value());  // ray-tracing round-off
  EXPECT_FALSE(target.Albedo(on + 5.0 * p.normal).has_value());
  EXPECT_FALSE(target.Albedo(on - kTargetPanelThicknessMm * p.normal).has_value());  // back
  EXPECT_FALSE(target.Albedo(PanelPoint(p, -1.0, 100.0)).has_value());
  EXPECT_FALSE(target.Albedo(PanelPoint(p, 100.0, p.height + 1.0)).has_value());
  EXPECT_FALSE(target.Albedo(Vector3d(0, 0, 1000)).has_value());  // prism interior
  EXPECT_FALSE(target.AlbedoArea(Vector3d(0, 0, 1000), 5.0).has_value());
}

struct Render {
  cv::Mat image;
  double mm_per_px;
  int margin;
};

// Head-on view of one panel: pixel (x, y) centre samples panel point
// u = (x - margin + 0.5) s, v = height - (y - margin + 0.5) s; top of the panel at the top.
Render RenderPanel(const RenderedTarget& target, int panel, double mm_per_px, bool area) {
  const TargetPanel& p = target.panels()[panel];
  Render r{cv::Mat(), mm_per_px, 20};
  const int w = static_cast<int>(std::ceil(p.width / mm_per_px)) + 2 * r.margin;
  const int h = static_cast<int>(std::ceil(p.height / mm_per_px)) + 2 * r.margin;
  r.image = cv::Mat(h, w, CV_8UC1, cv::Scalar(40));  // dark cabinet behind the target
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double u = (x - r.margin + 0.5) * mm_per_px;
      const double v = p.height - (y - r.margin + 0.5) * mm_per_px;
      const Vector3d point = PanelPoint(p, u, v);
      const std::optional<double> a =
          area ? target.AlbedoArea(point, mm_per_px) : target.Albedo(point);
      if (a) r.image.at<unsigned char>(y, x) = cv::saturate_cast<unsigned char>(*a * 255.0);
    }
  }
  return r;
}

// Returns the largest corner error found.
double ExpectDetected(const RenderedTarget& target, bool area, double max_corner_error_px) {
  double worst = 0.0;
  for (int panel = 0; panel < 3; ++panel) {
    const TargetPanel& p = target.panels()[panel];
    const Render r = RenderPanel(target, panel, 2.5, area);
    std::vector<int> ids;
    std::vector<std::vector<cv::Point2f>> corners, rejected;
    cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
    params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::detectMarkers(r.image, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50),
                             corners, ids, params, rejected);
    std::set<int> found(ids.begin(), ids.end());
    for (int id = 16 * panel; id < 16 * panel + 16; ++id) {
      EXPECT_TRUE(found.count(id)) << "panel " << panel << " id " << id << (area ? " area" : "");
    }
    EXPECT_EQ(found.size(), 16u);
    for (size_t i = 0; i < ids.size(); ++i) {
      EXPECT_TRUE(ids[i] >= 16 * panel && ids[i] < 16 * panel + 16) << "id " << ids[i];
      if (ids[i] < 16 * panel || ids[i] >= 16 * panel + 16) return 1e9;
      const TargetMarker& m = target.markers()[ids[i]];
      EXPECT_EQ(m.id, ids[i]);
      for (int k = 0; k < 4; ++k) {
        const Vector2d uv = PanelUv(p, m.corners[k]);
        const double x = r.margin + uv.x() / r.mm_per_px - 0.5;
        const double y = r.margin + (p.height - uv.y()) / r.mm_per_px - 0.5;
        EXPECT_NEAR(corners[i][k].x, x, max_corner_error_px) << "id " << ids[i] << " corner " << k;
        EXPECT_NEAR(corners[i][k].y, y, max_corner_error_px) << "id " << ids[i] << " corner " << k;
        worst = std::max({worst, std::abs(corners[i][k].x - x), std::abs(corners[i][k].y - y)});
      }
    }
  }
  return worst;
}

// A point-sampled render: edges are hard pixel steps, so the refined corners are only
// as good as the pixel grid allows (worst measured 0.46 px).
TEST(RenderedTargetTest, HeadOnRenderDecodesEveryMarkerWithCornersWithinAPixel) {
  double worst = 0.0;
  for (const TargetConfig& config : Configs())
    worst = std::max(worst, ExpectDetected(RenderedTarget(config), false, 0.6));
  std::printf("point-sampled render: worst corner error %.3f px\n", worst);
}

TEST(RenderedTargetTest, AreaRenderDecodesEveryMarkerWithSubpixelCorners) {
  // Anti-aliased edges let the sub-pixel refinement land closer than a point-sampled render
  // (worst measured 0.16 px).
  double worst = 0.0;
  for (const TargetConfig& config : Configs())
    worst = std::max(worst, ExpectDetected(RenderedTarget(config), true, 0.25));
  std::printf("area render: worst corner error %.3f px\n", worst);
}

// Mean of Albedo over an n x n midpoint grid of the footprint, points off the panel skipped.
double DenseMean(const RenderedTarget& target, const TargetPanel& p, const Vector3d& centre,
                 double side, int n) {
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double a = ((i + 0.5) / n - 0.5) * side;
      const double b = ((j + 0.5) / n - 0.5) * side;
      if (const auto albedo = target.Albedo(centre + a * p.right + b * p.up)) {
        sum += *albedo;
        ++count;
      }
    }
  }
  return sum / count;
}

TEST(RenderedTargetTest, AlbedoAreaIsTheMeanOverTheFootprint) {
  const RenderedTarget target(RotatedConfig());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const std::array<double, 4> sides = {0.8, 4.0, 13.0, 31.0};
  int mixed = 0;
  for (int panel = 0; panel < 3; ++panel) {
    const TargetPanel& p = target.panels()[panel];
    std::vector<Vector3d> centres;
    // Random points, one on a marker corner, and one straddling the panel's edge.
    for (int k = 0; k < 3; ++k)
      centres.push_back(PanelPoint(p, unit(rng) * p.width, unit(rng) * p.height));
    centres.push_back(target.markers()[16 * panel + 5].corners[2] + 0.37 * p.right);
    centres.push_back(PanelPoint(p, 2.0, 700.0));
    for (const Vector3d& c : centres) {
      for (double side : sides) {
        const std::optional<double> exact = target.AlbedoArea(c, side);
        ASSERT_TRUE(exact.has_value());
        const double dense = DenseMean(target, p, c, side, 1500);
        EXPECT_NEAR(*exact, dense, 1e-3) << "panel " << panel << " side " << side;
        mixed += *exact > 0.06 && *exact < 0.84;
      }
    }
  }
  EXPECT_GT(mixed, 5);  // the comparison exercised footprints over black/white edges
  // A vanishing footprint is a point sample.
  const Vector3d c =
      target.markers()[3].corners[0] + Vector3d(0, 0, -1.0) + target.panels()[0].right;
  EXPECT_DOUBLE_EQ(target.AlbedoArea(c, 0.0).value(), target.Albedo(c).value());
}

TEST(RenderedTargetTest, MeshIsThreeClosedOutwardBoxesWithFrontsOnThePanels) {
  for (const TargetConfig& config : Configs()) {
    const RenderedTarget target(config);
    const TriangleMesh mesh = target.Mesh();
    ASSERT_FALSE(mesh.triangles.empty());
    // Closed and consistently oriented: every directed edge meets its reverse exactly once.
    std::map<std::pair<int, int>, int> edges;
    for (const Eigen::Vector3i& t : mesh.triangles) {
      for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
    }
    for (const auto& [edge, count] : edges) {
      EXPECT_EQ(count, 1);
      EXPECT_EQ(edges.count({edge.second, edge.first}), 1u);
    }
    // Outward: positive enclosed volume, equal to three mitred (trapezoidal) slabs.
    const double t = kTargetPanelThicknessMm;
    const double w = config.panel_width_mm;
    double volume = 0.0;
    std::vector<double> front_area(3, 0.0);
    for (const Eigen::Vector3i& tri : mesh.triangles) {
      const Vector3d& a = mesh.vertices[tri[0]];
      const Vector3d& b = mesh.vertices[tri[1]];
      const Vector3d& c = mesh.vertices[tri[2]];
      volume += a.dot(b.cross(c)) / 6.0;
      const Vector3d n = (b - a).cross(c - a);
      for (int p = 0; p < 3; ++p) {
        const TargetPanel& panel = target.panels()[p];
        if (n.normalized().dot(panel.normal) > 1.0 - 1e-12 &&
            std::abs(panel.normal.dot(a - panel.origin)) < 1e-9) {
          front_area[p] += 0.5 * n.norm();
        }
      }
    }
    const double slab = config.panel_height_mm * t * (w + (w - 2.0 * std::sqrt(3.0) * t)) / 2.0;
    EXPECT_NEAR(volume, 3.0 * slab, 1e-6 * slab);
    for (int p = 0; p < 3; ++p) {
      EXPECT_NEAR(front_area[p], w * config.panel_height_mm, 1e-6) << p;
    }
    // Nothing pokes out in front of any panel.
    for (const Vector3d& v : mesh.vertices) {
      for (const TargetPanel& panel : target.panels()) {
        EXPECT_LE(panel.normal.dot(v - panel.origin), 1e-9);
      }
    }
  }
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/target.h"

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

namespace mirrorscan::virtual_cabinet {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

TargetConfig RotatedConfig() {
  TargetConfig c;
  c.center_mm = {35.0, -20.0};
  c.yaw_deg = 17.0;
  c.bottom_mm = 150.0;
  c.panel_width_mm = 450.0;
  c.panel_height_mm = 1500.0;
  c.marker_size_mm = 132.0;
  return c;
}

std::vector<TargetConfig> Configs() { return {TargetConfig{}, RotatedConfig()}; }

// Point coordinates in a panel's frame, computed here rather than trusted from the class.
Vector2d PanelUv(const TargetPanel& p, const Vector3d& x) {
  return {p.right.dot(x - p.origin), p.up.dot(x - p.origin)};
}

Vector3d PanelPoint(const TargetPanel& p, double u, double v) {
  return p.origin + u * p.right + v * p.up;
}

TEST(TargetTest, PanelNormalsAre120DegreesApartAndFaceTheRightWay) {
  for (const TargetConfig& config : Configs()) {
    const CalibrationTarget target(config);
    const auto& panels = target.panels();
    ASSERT_EQ(panels.size(), 3u);
    for (size_t i = 0; i < 3; ++i) {
      const TargetPanel& p = panels[i];
      EXPECT_NEAR(p.normal.norm(), 1.0, 1e-12);
      EXPECT_NEAR(p.right.norm(), 1.0, 1e-12);
      EXPECT_NEAR(p.up.norm(), 1.0, 1e-12);
      EXPECT_NEAR(p.normal.z(), 0.0, 1e-12);  // vertical panels
      EXPECT_NEAR((p.up - Vector3d::UnitZ()).norm(), 0.0, 1e-12);
      EXPECT_NEAR((p.right.cross(p.up) - p.normal).norm(), 0.0, 1e-12);
      EXPECT_DOUBLE_EQ(p.width, config.panel_width_mm);
      EXPECT_DOUBLE_EQ(p.height, config.panel_height_mm);
      EXPECT_NEAR(p.origin.z(), config.bottom_mm, 1e-9);
      for (size_t j = i + 1; j < 3; ++j) {
        const double angle = std::acos(std::clamp(p.normal.dot(panels[j].normal), -1.0, 1.0));
        EXPECT_NEAR(angle, 2.0 * kPi / 3.0, 1e-12) << i << " " << j;
      }
      // Outward: the prism axis lies behind every front face.
      const Vector3d axis(config.center_mm.x(), config.center_mm.y(), p.origin.z());
      EXPECT_LT(p.normal.dot(axis - p.origin), 0.0);
    }
    // Neighbouring panels share their vertical edges: the prism is closed.
    for (int i = 0; i < 3; ++i) {
      const Vector3d right_edge = panels[i].origin + panels[i].width * panels[i].right;
      int shared = 0;
      for (int j = 0; j < 3; ++j) shared += (right_edge - panels[j].origin).norm() < 1e-9;
      EXPECT_EQ(shared, 1) << "panel " << i;
    }
  }
  const CalibrationTarget target(TargetConfig{});
  const auto& panels = target.panels();
  EXPECT_NEAR((panels[0].normal - Vector3d(0, -1, 0)).norm(), 0.0, 1e-12);  // faces camera
  EXPECT_NEAR((panels[0].right - Vector3d(1, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_LT(panels[1].normal.x(), 0.0);  // back-left, towards the left mirror
  EXPECT_GT(panels[1].normal.y(), 0.0);
  EXPECT_GT(panels[2].normal.x(), 0.0);  // back-right
  EXPECT_GT(panels[2].normal.y(), 0.0);

  const TargetConfig rotated = RotatedConfig();
  const double yaw = rotated.yaw_deg * kPi / 180.0;
  EXPECT_NEAR(
      (CalibrationTarget(rotated).panels()[0].normal - Vector3d(std::sin(yaw), -std::cos(yaw), 0))
          .norm(),
      0.0, 1e-12);
}

TEST(TargetTest, MarkersAreSquaresOnTheirPanelsInOpenCvOrder) {
  for (const TargetConfig& config : Configs()) {
    const CalibrationTarget target(config);
    const double ms = config.marker_size_mm;
    const double module = ms / 6.0;
    ASSERT_EQ(target.markers().size(), 48u);
    std::set<int> ids;
    std::map<int, std::vector<std::pair<Vector2d, Vector2d>>> boxes;  // panel: min, max uv
    for (const TargetMarker& m : target.markers()) {
      ids.insert(m.id);
      EXPECT_EQ(m.panel, m.id / 16) << m.id;
      ASSERT_GE(m.panel, 0);
      ASSERT_LT(m.panel, 3);
      const TargetPanel& p = target.panels()[m.panel];
      const auto& c = m.corners;
      for (int k = 0; k < 4; ++k) {
        EXPECT_NEAR(p.normal.dot(c[k] - p.origin), 0.0, 1e-9) << m.id;  // coplanar
        EXPECT_NEAR((c[(k + 1) % 4] - c[k]).norm(), ms, 1e-9) << m.id;
        const Vector2d uv = PanelUv(p, c[k]);
        // Inside the panel with at least one white module around it.
        EXPECT_GE(uv.x(), module - 1e-9);
        EXPECT_LE(uv.x(), p.width - module + 1e-9);
        EXPECT_GE(uv.y(), module - 1e-9);
        EXPECT_LE(uv.y(), p.height - module + 1e-9);
      }
      EXPECT_NEAR((c[2] - c[0]).norm(), ms * std::sqrt(2.0), 1e-9);
      EXPECT_NEAR((c[3] - c[1]).norm(), ms * std::sqrt(2.0), 1e-9);
      EXPECT_NEAR((c[1] - c[0]).dot(p.right), ms, 1e-9) << m.id;  // TL -> TR along right
      EXPECT_GT(c[0].z(), c[3].z()) << m.id;                      // TL above BL
      EXPECT_NEAR((c[0] - c[3]).dot(p.up), ms, 1e-9) << m.id;
      boxes[m.panel].push_back({PanelUv(p, c[3]), PanelUv(p, c[1])});
    }
    EXPECT_EQ(ids.size(), 48u);
    EXPECT_EQ(*ids.begin(), 0);
    EXPECT_EQ(*ids.rbegin(), 47);
    // No overlap, and neighbours keep two modules of white between them (quiet zones).
    for (const auto& [panel, list] : boxes) {
      EXPECT_EQ(list.size(), 16u);
      for (size_t i = 0; i < list.size(); ++i) {
        for (size_t j = i + 1; j < list.size(); ++j) {
          const double gap_u = std::max(list[j].first.x() - list[i].second.x(),
                                        list[i].first.x() - list[j].second.x());
          const double gap_v = std::max(list[j].first.y() - list[i].second.y(),
                                        list[i].first.y() - list[j].second.y());
          EXPECT_GE(std::max(gap_u, gap_v), 2.0 * module - 1e-9) << panel << " " << i << " " << j;
        }
      }
    }
  }
}

// The expected module colours, straight from OpenCV's own drawing of each marker.
cv::Mat DrawModules(int id) {
  cv::Mat img;
  cv::aruco::drawMarker(cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), id, 6, img, 1);
  return img;
}

TEST(TargetTest, AlbedoAtModuleCentresMatchesTheDictionary) {
  for (const TargetConfig& config : Configs()) {
    const CalibrationTarget target(config);
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

TEST(TargetTest, AlbedoIsOnlyDefinedOnFrontFaces) {
  const CalibrationTarget target(TargetConfig{});
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
Render RenderPanel(const CalibrationTarget& target, int panel, double mm_per_px, bool area) {
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
double ExpectDetected(const CalibrationTarget& target, bool area, double max_corner_error_px) {
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
TEST(TargetTest, HeadOnRenderDecodesEveryMarkerWithCornersWithinAPixel) {
  double worst = 0.0;
  for (const TargetConfig& config : Configs())
    worst = std::max(worst, ExpectDetected(CalibrationTarget(config), false, 0.6));
  std::printf("point-sampled render: worst corner error %.3f px\n", worst);
}

TEST(TargetTest, AreaRenderDecodesEveryMarkerWithSubpixelCorners) {
  // Anti-aliased edges let the sub-pixel refinement land closer than a point-sampled render
  // (worst measured 0.16 px).
  double worst = 0.0;
  for (const TargetConfig& config : Configs())
    worst = std::max(worst, ExpectDetected(CalibrationTarget(config), true, 0.25));
  std::printf("area render: worst corner error %.3f px\n", worst);
}

// Mean of Albedo over an n x n midpoint grid of the footprint, points off the panel skipped.
double DenseMean(const CalibrationTarget& target, const TargetPanel& p, const Vector3d& centre,
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

TEST(TargetTest, AlbedoAreaIsTheMeanOverTheFootprint) {
  const CalibrationTarget target(RotatedConfig());
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

TEST(TargetTest, MeshIsThreeClosedOutwardBoxesWithFrontsOnThePanels) {
  for (const TargetConfig& config : Configs()) {
    const CalibrationTarget target(config);
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

TEST(TargetTest, ToJsonListsEveryMarkerCorner) {
  const CalibrationTarget target(RotatedConfig());
  const nlohmann::json json = nlohmann::json::parse(target.ToJson().dump());
  EXPECT_EQ(json.at("dictionary"), "DICT_4X4_50");
  EXPECT_DOUBLE_EQ(json.at("marker_size_mm").get<double>(), 132.0);
  ASSERT_EQ(json.at("panels").size(), 3u);
  EXPECT_DOUBLE_EQ(json.at("config").at("yaw_deg").get<double>(), 17.0);
  ASSERT_EQ(json.at("markers").size(), 48u);
  for (const TargetMarker& m : target.markers()) {
    const nlohmann::json& j = json.at("markers").at(m.id);
    EXPECT_EQ(j.at("id").get<int>(), m.id);
    EXPECT_EQ(j.at("panel").get<int>(), m.panel);
    for (int k = 0; k < 4; ++k) {
      const auto xyz = j.at("corners").at(k).get<std::vector<double>>();
      ASSERT_EQ(xyz.size(), 3u);
      EXPECT_NEAR((Vector3d(xyz[0], xyz[1], xyz[2]) - m.corners[k]).norm(), 0.0, 1e-9);
    }
  }
  const auto normal = json.at("panels").at(1).at("normal").get<std::vector<double>>();
  EXPECT_NEAR((Vector3d(normal[0], normal[1], normal[2]) - target.panels()[1].normal).norm(), 0.0,
              1e-12);
}

TargetConfig ParseTarget(const std::string& text) {
  const nlohmann::json json = JsonReader::ParseText(text, "scene.json");
  return TargetConfig::Parse(JsonReader(json, "scene.json").Object("target"));
}

TEST(TargetTest, ConfigDefaultsAndKeys) {
  const TargetConfig d = ParseTarget(R"({"target": {}})");
  EXPECT_EQ(d.center_mm, Vector2d(0, 0));
  EXPECT_EQ(d.yaw_deg, 0.0);
  EXPECT_EQ(d.bottom_mm, 200.0);
  EXPECT_EQ(d.panel_width_mm, 420.0);
  EXPECT_EQ(d.panel_height_mm, 1600.0);
  EXPECT_EQ(d.marker_size_mm, 150.0);
  const TargetConfig c = ParseTarget(
      R"({"target": {"center_mm": [35, -20], "yaw_deg": 17, "bottom_mm": 150,
          "panel_width_mm": 450, "panel_height_mm": 1500, "marker_size_mm": 132}})");
  EXPECT_EQ(c.center_mm, Vector2d(35, -20));
  EXPECT_EQ(c.yaw_deg, 17.0);
  EXPECT_EQ(c.bottom_mm, 150.0);
  EXPECT_EQ(c.panel_width_mm, 450.0);
  EXPECT_EQ(c.panel_height_mm, 1500.0);
  EXPECT_EQ(c.marker_size_mm, 132.0);
}

TEST(TargetTest, BadConfigNamesTheKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"colour": 1})", "target.colour"},
      {R"({"center_mm": [1, 2, 3]})", "target.center_mm"},
      {R"({"center_mm": "middle"})", "target.center_mm"},
      {R"({"yaw_deg": "north"})", "target.yaw_deg"},
      {R"({"bottom_mm": -5})", "target.bottom_mm"},
      {R"({"panel_width_mm": 0})", "target.panel_width_mm"},
      {R"({"panel_height_mm": -1600})", "target.panel_height_mm"},
      {R"({"marker_size_mm": 0})", "target.marker_size_mm"},
      {R"({"marker_size_mm": 151})", "target.marker_size_mm"},    // no quiet zone left
      {R"({"panel_height_mm": 1000})", "target.marker_size_mm"},  // 150 mm no longer fits
  };
  for (const auto& [body, key] : cases) {
    try {
      ParseTarget(R"({"target": )" + body + "}");
      ADD_FAILURE() << "accepted " << body;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("scene.json: " + key + ":"), std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

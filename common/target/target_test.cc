#include "common/target/target.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "common/target/target_test_util.h"

namespace mirrorscan {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

using target_test::Configs;
using target_test::PanelUv;
using target_test::RotatedConfig;

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
      EXPECT_NEAR((m.top_left_in_panel - PanelUv(p, c[0])).norm(), 0.0, 1e-9) << m.id;
      EXPECT_NEAR((target.PanelCoordinates(m.panel, c[2]) - PanelUv(p, c[2])).norm(), 0.0, 1e-9);
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
}  // namespace mirrorscan

#include "boards/virtual/scene.h"

#include <cmath>
#include <functional>

#include <gtest/gtest.h>

#include "common/config/json_reader.h"

namespace mirrorscan::virtual_cabinet {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    Scene::Parse(JsonReader::ParseText(text, "scene.json"), "scene.json", ".");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneTest, ABodysAlbedoIsPerRegion) {
  const std::string error = ErrorOf(R"({"subject": {"type": "body", "albedo": 0.5}})");
  EXPECT_NE(error.find("subject.albedo"), std::string::npos) << error;
  EXPECT_NE(error.find("skin_albedo"), std::string::npos) << error;
}

// The defaults are the cabinet docs/boards.md draws (docs/cabinet-design.md chose it).
TEST(SceneTest, DefaultsAreTheCabinetForPeople) {
  const Scene scene = Scene::Parse(nlohmann::json::object(), "scene.json", ".");
  ASSERT_EQ(scene.cameras.size(), 3u);
  EXPECT_EQ(scene.cameras[0].camera.intrinsics.width, 1024);
  EXPECT_EQ(scene.cameras[0].camera.intrinsics.height, 768);
  EXPECT_EQ(scene.cameras[0].fps, 30.0);
  EXPECT_EQ(scene.lasers.count, 3);
  EXPECT_EQ(scene.lasers.spacing_mm, 200.0);
  EXPECT_EQ(scene.cameras[0].camera.intrinsics.fx, 1150.0);
  EXPECT_NEAR(scene.cameras[0].camera.CenterInWorld().z(), 2400.0, 1e-9);
  EXPECT_NEAR(scene.cameras[1].camera.CenterInWorld().z(), 1350.0, 1e-9);
  // The third camera, 300 mm above the floor, looks up under the bust and the chin.
  EXPECT_EQ(scene.cameras[2].name, "up");
  EXPECT_NEAR(scene.cameras[2].camera.CenterInWorld().z(), 300.0, 1e-9);
  EXPECT_GT(scene.cameras[2].camera.cam_from_world.rotation.toRotationMatrix().row(2).z(),
            std::sin(27 * M_PI / 180));  // 28° up
  EXPECT_EQ(scene.lasers.emitters_xy.size(), 4u);
  EXPECT_EQ(scene.lasers.power, 2.0);
  EXPECT_EQ(scene.lasers.fan_deg, 90.0);
  EXPECT_EQ(scene.frames, 350);  // the top laser to 2100 mm
  EXPECT_EQ(scene.mirrors[0].width, 1000.0);
  EXPECT_EQ(scene.mirrors[0].height, 2100.0);
  EXPECT_EQ(scene.mirrors[0].origin, Eigen::Vector3d(0, 900, 0));
  // The mirrors stand 120° apart: their normals are 60° apart (180° - 120°).
  const double angle = std::acos(scene.mirrors[0].plane.normal.dot(scene.mirrors[1].plane.normal));
  EXPECT_NEAR(angle * 180.0 / M_PI, 60.0, 1e-9);
  // Normals point towards the subject at the origin.
  for (const auto& m : scene.mirrors)
    EXPECT_GT(m.plane.SignedDistance(Eigen::Vector3d(0, 0, 1000)), 0);
  EXPECT_LT(scene.mirrors[0].Corners()[1].x(), 0);  // left mirror on the camera's left
  // Panels lie parallel behind the mirrors at the stated offset.
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(scene.mirrors[i].plane.SignedDistance(scene.panels[i].origin), -6.0, 1e-9);
    EXPECT_GT(scene.panels[i].width, scene.mirrors[i].width);
  }
  EXPECT_EQ(scene.subject.type, "mannequin");
  EXPECT_FALSE(scene.target.has_value());
}

TEST(SceneTest, BadValuesGiveOneErrorNamingTheKey) {
  EXPECT_EQ(ErrorOf(R"({"lasers": {"count": 5}})"),
            "scene.json: lasers.count: must be in [1, 3], got 5");
  EXPECT_EQ(ErrorOf(R"({"lazers": {}})").rfind("scene.json: lazers: unknown key", 0), 0u);
  EXPECT_EQ(
      ErrorOf(R"({"cameras": [{"name": "a", "position_mm": [0, 0], "look_at_mm": [0, 1, 0]}]})"),
      "scene.json: cameras[0].position_mm: expected an array of 3 numbers");
  EXPECT_EQ(
      ErrorOf(R"({"cameras": [{"name": "a", "position_mm": [0,0,0], "look_at_mm": [0,0,0]}]})"),
      "scene.json: cameras[0].look_at_mm: must differ from position_mm");
  EXPECT_EQ(ErrorOf(R"({"sensor": {"noise": 1}})"),
            "scene.json: sensor.noise: expected true or false");
  EXPECT_EQ(ErrorOf(R"({"mirrors": {"angle_deg": "wide"}})"),
            "scene.json: mirrors.angle_deg: expected a number");
  EXPECT_EQ(ErrorOf(R"({"seed": 1.5})"), "scene.json: seed: expected a whole number");
  EXPECT_EQ(ErrorOf(R"({"lasers": {"fan_deg": 0}})"),
            "scene.json: lasers.fan_deg: must be in [1, 360], got 0");
  EXPECT_EQ(ErrorOf(R"({"cameras": []})"), "scene.json: cameras: expected one to 3 cameras");
  EXPECT_NE(ErrorOf(R"({"subject": {"type": "dragon"}})").find("subject.type"), std::string::npos);
  EXPECT_NE(ErrorOf(R"({"target": {"yaw_deg": "x"}})").find("target.yaw_deg"), std::string::npos);
}

TEST(SceneTest, TakesUpToThreeCamerasNamedOnceAtOneFrameRate) {
  const std::string upper =
      R"({"name": "upper", "position_mm": [0,-1800,2400], "look_at_mm": [0,300,1550]})";
  const std::string lower =
      R"({"name": "lower", "position_mm": [0,-1800,1350], "look_at_mm": [0,300,450]})";
  const std::string up =
      R"({"name": "up", "position_mm": [0,-1800,300], "look_at_mm": [0,300,1400]})";
  const Scene scene =
      Scene::Parse(nlohmann::json::parse("{\"cameras\": [" + upper + "," + lower + "," + up + "]}"),
                   "scene.json", ".");
  ASSERT_EQ(scene.cameras.size(), 3u);
  EXPECT_NEAR(scene.cameras[2].camera.CenterInWorld().z(), 300.0, 1e-9);
  EXPECT_EQ(
      ErrorOf("{\"cameras\": [" + upper + "," + lower + "," + up + "," +
              R"({"name": "x", "position_mm": [0,-1800,900], "look_at_mm": [0,0,900]})" + "]}"),
      "scene.json: cameras: expected one to 3 cameras");
  EXPECT_EQ(ErrorOf("{\"cameras\": [" + upper + "," + lower + "," + upper + "]}"),
            "scene.json: cameras: camera names must differ");
  EXPECT_EQ(
      ErrorOf(
          "{\"cameras\": [" + upper + "," + lower + "," +
          R"({"name": "up", "position_mm": [0,-1800,300], "look_at_mm": [0,300,1400], "fps": 60})" +
          "]}"),
      "scene.json: cameras: all cameras must run at the same fps");
}

TEST(SceneTest, EmittersAreAListOfPositionsOnTheSlide) {
  const Scene scene = Scene::Parse(
      nlohmann::json{{"lasers", {{"emitters_mm", {{0, -900}, {-600, -600}}}}}}, "scene.json", ".");
  ASSERT_EQ(scene.lasers.emitters_xy.size(), 2u);
  EXPECT_EQ(scene.lasers.emitters_xy[1], Eigen::Vector2d(-600, -600));
  EXPECT_EQ(ErrorOf(R"({"lasers": {"emitter_mm": [0, -900], "emitters_mm": [[0, -900]]}})"),
            "scene.json: lasers.emitters_mm: give emitter_mm (one emitter) or emitters_mm (a "
            "list), not both");
  EXPECT_EQ(ErrorOf(R"({"lasers": {"emitters_mm": []}})"),
            "scene.json: lasers.emitters_mm: expected a list of 1 to 8 [x, y] positions");
  EXPECT_EQ(ErrorOf(R"({"lasers": {"emitters_mm": [[0, -900, 5]]}})"),
            "scene.json: lasers.emitters_mm: each emitter is [x, y] in mm");
  EXPECT_EQ(
      ErrorOf(
          R"({"mirrors": {"left_bump_mm": 1}, "lasers": {"emitters_mm": [[0, -900], [600, -600]]}})"),
      "scene.json: lasers.emitters_mm: a bumped mirror's light is modelled from one emitter "
      "only (give lasers.emitter_mm)");
  EXPECT_EQ(ErrorOf(R"({"mirrors": {"left_bump_mm": 1}})"),
            "scene.json: lasers.emitters_mm: a bumped mirror's light is modelled from one emitter "
            "only (give lasers.emitter_mm)");
}

TEST(SceneTest, ShippedScenesLoad) {
  for (const char* name : {"mannequin", "cuboid", "cylinder", "calibration"}) {
    const Scene scene = Scene::Load(std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/" +
                                    name + ".json");
    EXPECT_FALSE(scene.cameras.empty()) << name;
  }
}

TEST(SceneTest, MirrorBumpTiltsTheNormalSmoothly) {
  Scene scene = Scene::Parse(nlohmann::json{{"mirrors", {{"right_bump_mm", 2.0}}},
                                            {"lasers", {{"emitter_mm", {0, -900}}}}},
                             "scene.json", ".");
  const Mirror& m = scene.mirrors[1];
  // Flat at the centre, tilted towards the edges, zero displacement on the rim.
  EXPECT_LT((m.SurfaceNormal({m.width / 2, m.height / 2}) - m.plane.normal).norm(), 1e-12);
  EXPECT_NEAR(m.Displacement({m.width / 2, m.height / 2}), 2.0, 1e-12);
  EXPECT_NEAR(m.Displacement({0, m.height / 2}), 0.0, 1e-12);
  EXPECT_GT((m.SurfaceNormal({m.width * 0.9, m.height / 2}) - m.plane.normal).norm(), 1e-4);
  EXPECT_LT((scene.mirrors[0].SurfaceNormal({100, 100}) - scene.mirrors[0].plane.normal).norm(),
            1e-15);
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

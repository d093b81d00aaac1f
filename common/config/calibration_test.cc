#include "common/config/calibration.h"

#include <cmath>
#include <functional>
#include <random>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// A cabinet like the virtual one: a camera in front, mirrors at 120° behind.
Calibration Example() {
  Calibration c;
  c.source = "test";
  c.target_id = "virtual-3panel-aruco48";
  CalibrationCamera cam;
  cam.name = "upper";
  cam.camera.intrinsics.fx = 1400.5;
  cam.camera.intrinsics.fy = 1399.25;
  cam.camera.intrinsics.k1 = -0.08;
  cam.camera.intrinsics.p1 = 3e-4;
  cam.camera.cam_from_world = LookAt({0, -1800, 2150}, {0, 300, 1350});
  cam.views.push_back({"center", std::nullopt, {}});
  cam.views.push_back({"left", "left", {{100, 100}, {400, 100}, {400, 500}, {100, 500}}});
  cam.views.push_back({"right", "right", {{600, 100}, {900, 100}, {900, 500}, {600, 500}}});
  c.cameras.push_back(cam);
  const double phi = 30.0 * M_PI / 180.0;
  for (int side = 0; side < 2; ++side) {
    const double sign = side == 0 ? -1.0 : 1.0;
    CalibrationMirror m;
    m.name = side == 0 ? "left" : "right";
    m.plane = Plane::FromPointNormal({0, 600, 100},
                                     Eigen::Vector3d(-sign * std::sin(phi), -std::cos(phi), 0));
    m.corners_mm = {{0, 600, 100},
                    {0, 600, 1800},
                    {sign * 500, 600 - 288.675, 1800},
                    {sign * 500, 600 - 288.675, 100}};
    m.panel_offset_mm = 6.0;
    c.mirrors.push_back(m);
  }
  c.lasers = CalibrationLasers{3, 200.0, Eigen::Vector3d::UnitZ(), -50.0, 150.0, {}, std::nullopt};
  c.residuals.reprojection_rms_px = 0.08;
  c.residuals.views.push_back({"upper", "left", 0.09, 0.3, 256});
  return c;
}

TEST(CalibrationTest, RoundTripsThroughJson) {
  const Calibration c = Example();
  const nlohmann::json json = c.ToJson();
  EXPECT_EQ(json["schema"], "mirrorscan.calibration");
  EXPECT_EQ(json["version"], 1);
  const Calibration back = Calibration::ParseText(json.dump(2), "calibration.json");
  EXPECT_EQ(back.ContentHash(), c.ContentHash());
  EXPECT_EQ(back.ToJson(), Calibration::Parse(back.ToJson(), "x").ToJson());
  ASSERT_EQ(back.cameras.size(), 1u);
  const Camera& cam = back.cameras[0].camera;
  EXPECT_DOUBLE_EQ(cam.intrinsics.fx, 1400.5);
  EXPECT_DOUBLE_EQ(cam.intrinsics.k1, -0.08);
  const Eigen::Vector3d p(120, 300, 900);
  EXPECT_LT((*cam.ProjectWorld(p) - *c.cameras[0].camera.ProjectWorld(p)).norm(), 1e-9);
  ASSERT_NE(back.FindMirror("right"), nullptr);
  EXPECT_LT((back.FindMirror("right")->plane.normal - c.mirrors[1].plane.normal).norm(), 1e-15);
  EXPECT_EQ(back.FindMirror("left")->corners_mm.size(), 4u);
  ASSERT_TRUE(back.lasers);
  EXPECT_DOUBLE_EQ(back.lasers->PlaneAt(2, 1.0).offset, -(-50.0 + 150.0 + 400.0));
  EXPECT_FALSE(back.lasers->readback_offset_mm);

  // Measured per-laser offsets and readback offset round-trip, count in the hash, and
  // place the planes.
  Calibration measured = c;
  measured.lasers->offsets_mm = {0.0, 200.3, 399.6};
  measured.lasers->readback_offset_mm = 50.01;
  const Calibration measured_back =
      Calibration::ParseText(measured.ToJson().dump(), "calibration.json");
  EXPECT_NE(measured_back.ContentHash(), c.ContentHash());
  EXPECT_EQ(measured_back.lasers->offsets_mm, measured.lasers->offsets_mm);
  EXPECT_EQ(measured_back.lasers->readback_offset_mm, 50.01);
  EXPECT_DOUBLE_EQ(measured_back.lasers->PlaneAt(2, 1.0).offset, -(-50.0 + 150.0 + 399.6));
  for (const auto& [offsets, problem] : std::vector<std::pair<nlohmann::json, std::string>>{
           {{0.0, 200.0}, "lasers.offsets_mm: expected an array of 3 numbers"},
           {{1.0, 200.0, 400.0}, "lasers.offsets_mm: must start with laser 0's own offset, 0"},
           {{0.0, 400.0, 200.0}, "lasers.offsets_mm: lasers must be ordered upwards"}}) {
    nlohmann::json bad = measured.ToJson();
    bad.erase("content_hash");
    bad["lasers"]["offsets_mm"] = offsets;
    try {
      Calibration::Parse(bad, "calibration.json");
      ADD_FAILURE() << offsets;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(problem), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(back.residuals.views.at(0).points, 256);
  EXPECT_EQ(back.target_id, "virtual-3panel-aruco48");
}

TEST(CalibrationTest, ViewRegions) {
  const Calibration c = Example();
  const CalibrationCamera& cam = c.cameras[0];
  EXPECT_EQ(cam.ViewAt({200, 200})->name, "left");
  EXPECT_EQ(cam.ViewAt({700, 450})->name, "right");
  EXPECT_EQ(cam.ViewAt({500, 300})->name, "center");
  EXPECT_EQ(cam.ViewAt({200, 600})->name, "center");
}

TEST(CalibrationTest, HashFollowsGeometryNotResiduals) {
  Calibration c = Example();
  const std::string hash = c.ContentHash();
  EXPECT_EQ(hash.size(), 16u);
  c.residuals.reprojection_rms_px = 3.0;
  c.source = "other";
  EXPECT_EQ(c.ContentHash(), hash);
  c.mirrors[0].plane.offset += 0.01;
  EXPECT_NE(c.ContentHash(), hash);
}

TEST(CalibrationTest, ErrorsNameFileAndKey) {
  const nlohmann::json good = Example().ToJson();
  auto error_with = [&](const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json j = good;
    edit(j);
    return ErrorOf([&] { Calibration::Parse(j, "c.json"); });
  };
  EXPECT_EQ(error_with([](auto&) {}), "");
  EXPECT_EQ(error_with([](auto& j) { j["version"] = 2; }),
            "c.json: version: unsupported version 2 (this build reads 1)");
  EXPECT_EQ(error_with([](auto& j) { j["schema"] = "other"; }),
            "c.json: schema: expected \"mirrorscan.calibration\"");
  EXPECT_EQ(error_with([](auto& j) {
              j["mirrors"][1]["normal"] = {0, 0.5, 0};
            }),
            "c.json: mirrors[1].normal: must be a unit vector");
  EXPECT_EQ(error_with([](auto& j) {
              j["cameras"][0]["cam_from_world"]["rotation"] = {{1, 0, 0}, {0, 1, 0}, {0, 0, -1}};
            }),
            "c.json: cameras[0].cam_from_world.rotation: must be a proper rotation "
            "(orthonormal, determinant +1)");
  EXPECT_EQ(error_with([](auto& j) { j["cameras"][0]["views"][1]["mirror"] = "top"; }),
            "c.json: cameras[0].views: view \"left\" names unknown mirror \"top\"");
  EXPECT_EQ(error_with([](auto& j) { j["cameras"][0]["K"][0][1] = 0.5; }),
            "c.json: cameras[0].K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]");
  EXPECT_EQ(error_with([](nlohmann::json& j) {
              j["mirrors"][0]["offset_mm"] = j["mirrors"][0]["offset_mm"].get<double>() + 0.5;
            }),
            "c.json: content_hash: does not match the contents (file edited or corrupted)");
  EXPECT_EQ(error_with([](auto& j) { j["cameras"][0]["fx"] = 1.0; }),
            "c.json: cameras[0].fx: unknown key (expected one of: name, width, height, fps, K, "
            "distortion, cam_from_world, views)");
  EXPECT_EQ(error_with([](auto& j) { j["cameras"][0]["views"][1].erase("outline_px"); }),
            "c.json: cameras[0].views[1].outline_px: missing (a mirror view needs its region)");
  // Without a content hash a hand-edited file is accepted, validated as usual.
  EXPECT_EQ(error_with([](auto& j) {
              j.erase("content_hash");
              j["mirrors"][0]["offset_mm"] = 12.0;
            }),
            "c.json: mirrors[0].corners_mm: corners must lie in the mirror plane (within 1 mm)");
  EXPECT_EQ(ErrorOf([] { Calibration::ParseText("{\"schema\": ", "c.json"); }),
            "c.json: not valid JSON at byte 12");
  EXPECT_EQ(ErrorOf([] { Calibration::ParseText("[1e999]", "c.json"); }),
            "c.json: not valid JSON (a number out of range)");
  EXPECT_EQ(ErrorOf([] { Calibration::Load("/nonexistent/c.json"); }),
            "/nonexistent/c.json: cannot open file");
}

// Up to three cameras (the third looking up under the bust; docs/cabinet-design.md), each
// named once.
TEST(CalibrationTest, TakesOneToThreeNamedCameras) {
  auto with_cameras = [](const std::vector<std::string>& names) {
    Calibration c = Example();
    const CalibrationCamera camera = c.cameras[0];
    c.cameras.clear();
    for (const std::string& name : names) {
      c.cameras.push_back(camera);
      c.cameras.back().name = name;
    }
    nlohmann::json j = c.ToJson();
    j.erase("content_hash");
    return j;
  };
  const Calibration three = Calibration::Parse(with_cameras({"upper", "lower", "up"}), "c.json");
  ASSERT_EQ(three.cameras.size(), 3u);
  EXPECT_EQ(three.cameras[2].name, "up");
  EXPECT_EQ(ErrorOf([&] {
              Calibration::Parse(with_cameras({"a", "b", "c", "d"}), "c.json");
            }),
            "c.json: cameras: expected one to 3 cameras");
  EXPECT_EQ(ErrorOf([&] { Calibration::Parse(with_cameras({}), "c.json"); }),
            "c.json: cameras: expected one to 3 cameras");
  EXPECT_EQ(ErrorOf([&] {
              Calibration::Parse(with_cameras({"upper", "lower", "upper"}), "c.json");
            }),
            "c.json: cameras: camera names must differ");
}

// Random mutations of a valid file: every outcome is a parsed calibration or a
// ConfigError, never a crash or another exception.
TEST(CalibrationTest, MutatedJsonNeverCrashes) {
  Calibration example = Example();  // with every optional key, so they are mutated too
  example.lasers->offsets_mm = {0.0, 200.3, 399.6};
  example.lasers->readback_offset_mm = 50.0;
  const std::string text = example.ToJson().dump();
  std::mt19937 rng(7);
  const std::vector<nlohmann::json> replacements = {
      nullptr, 0,         -1,   1e308,       "x", nlohmann::json::array(), nlohmann::json::object(),
      {1, 2},  {1, 2, 3}, true, std::nan("")};
  int rejected = 0, accepted = 0;
  for (int i = 0; i < 3000; ++i) {
    nlohmann::json j = nlohmann::json::parse(text);
    // Replace one random value anywhere in the tree.
    std::vector<nlohmann::json*> nodes;
    std::function<void(nlohmann::json&)> collect = [&](nlohmann::json& n) {
      nodes.push_back(&n);
      if (n.is_structured())
        for (auto& c : n) collect(c);
    };
    collect(j);
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      *nodes[rng() % nodes.size()] = replacements[rng() % replacements.size()];
      nodes.clear();
      collect(j);
    }
    std::string mutated = j.dump();
    // And sometimes damage the text itself.
    if (rng() % 4 == 0 && !mutated.empty())
      mutated[rng() % mutated.size()] = "{}[],:\"0-e"[rng() % 10];
    if (rng() % 8 == 0) mutated.resize(rng() % mutated.size());
    try {
      Calibration::ParseText(mutated, "fuzz.json");
      ++accepted;
    } catch (const ConfigError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 1000);
  EXPECT_GT(accepted, 0);  // e.g. a changed residual or source
}

}  // namespace
}  // namespace mirrorscan

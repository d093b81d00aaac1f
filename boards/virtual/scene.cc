#include "boards/virtual/scene.h"

#include <cmath>
#include <numbers>

#include "common/config/calibration.h"
#include "common/config/json_reader.h"

namespace mirrorscan::virtual_cabinet {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Vector3d Vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

nlohmann::json DefaultCameras() {
  // Modelled on the paper's Fig. 1: an upper and a lower camera in front of the subject,
  // both looking down so that the laser planes they triangulate are never seen edge-on:
  // the upper camera serves heights above ~950 mm, the lower one those below. The upper
  // one at 2400 mm sees a 2.05 m person's back in the mirrors above the shoulders. The
  // third, 300 mm above the floor and 28 degrees up, sees what faces down: the underside
  // of a bust, the armpits, the chin (docs/cabinet-design.md).
  return nlohmann::json::array(
      {{{"name", "upper"}, {"position_mm", {0, -1800, 2400}}, {"look_at_mm", {0, 300, 1550}}},
       {{"name", "lower"}, {"position_mm", {0, -1800, 1350}}, {"look_at_mm", {0, 300, 450}}},
       {{"name", "up"}, {"position_mm", {0, -1800, 300}}, {"look_at_mm", {0, 300, 1400}}}});
}

SceneCamera ParseCamera(const JsonReader& r) {
  r.AllowOnly({"name", "position_mm", "look_at_mm", "width", "height", "f_px", "fx", "fy", "cx",
               "cy", "distortion", "fps"});
  SceneCamera c;
  c.name = r.String("name");
  if (c.name.empty()) r.Fail("name", "must not be empty");
  CameraIntrinsics& k = c.camera.intrinsics;
  k.width = r.Integer("width", 1024, 16, 16384);
  k.height = r.Integer("height", 768, 16, 16384);
  const double f = r.Number("f_px", 1150.0, 1.0, 1e6);
  k.fx = r.Number("fx", f, 1.0, 1e6);
  k.fy = r.Number("fy", f, 1.0, 1e6);
  k.cx = r.Number("cx", (k.width - 1) / 2.0, -k.width, 2.0 * k.width);
  k.cy = r.Number("cy", (k.height - 1) / 2.0, -k.height, 2.0 * k.height);
  const auto d = r.Numbers("distortion", 5, std::vector<double>{-0.08, 0.05, 3e-4, -2e-4, 0.0});
  for (double x : d) {
    if (std::abs(x) > 10) r.Fail("distortion", "coefficients must be within ±10");
  }
  k.k1 = d[0], k.k2 = d[1], k.p1 = d[2], k.p2 = d[3], k.k3 = d[4];
  c.fps = r.Number("fps", 30.0, 0.1, 1000.0);
  const Eigen::Vector3d position = Vec3(r.Numbers("position_mm", 3));
  const Eigen::Vector3d look_at = Vec3(r.Numbers("look_at_mm", 3));
  if ((look_at - position).norm() < 1.0) r.Fail("look_at_mm", "must differ from position_mm");
  const Eigen::Vector3d dir = (look_at - position).normalized();
  if (std::abs(dir.z()) > 0.999) r.Fail("look_at_mm", "camera must not look straight up or down");
  c.camera.cam_from_world = LookAt(position, look_at);
  // Corners of the image must unproject, or the distortion model folds over.
  for (double u : {-0.5, k.width - 0.5}) {
    for (double v : {-0.5, k.height - 0.5}) {
      if (!k.Unproject({u, v}))
        r.Fail("distortion", "distortion does not invert at the image corners");
    }
  }
  return c;
}

}  // namespace

Eigen::Vector2d Mirror::Local(const Eigen::Vector3d& point) const {
  const Eigen::Vector3d d = point - origin;
  return {d.dot(along), d.dot(up)};
}

bool Mirror::Contains(const Eigen::Vector3d& point_in_plane) const {
  const Eigen::Vector2d l = Local(point_in_plane);
  return l.x() >= 0.0 && l.x() <= width && l.y() >= 0.0 && l.y() <= height;
}

double Mirror::Displacement(const Eigen::Vector2d& local) const {
  if (bump_mm == 0.0) return 0.0;
  const double a = 2.0 * local.x() / width - 1.0, b = 2.0 * local.y() / height - 1.0;
  return bump_mm * (1.0 - a * a) * (1.0 - b * b);
}

Eigen::Vector3d Mirror::SurfaceNormal(const Eigen::Vector2d& local) const {
  if (bump_mm == 0.0) return plane.normal;
  const double a = 2.0 * local.x() / width - 1.0, b = 2.0 * local.y() / height - 1.0;
  const double d_da = bump_mm * (-2.0 * a) * (2.0 / width) * (1.0 - b * b);
  const double d_db = bump_mm * (1.0 - a * a) * (-2.0 * b) * (2.0 / height);
  return (plane.normal - d_da * along - d_db * up).normalized();
}

std::optional<Ray3d> Mirror::Reflect(const Ray3d& ray) const {
  const auto t = IntersectRayPlane(ray, plane, 1e-6);
  if (!t) return std::nullopt;
  Eigen::Vector3d hit = ray.At(*t);
  if (!Contains(hit)) return std::nullopt;
  Eigen::Vector2d local = Local(hit);
  if (bump_mm != 0.0) {
    // Meet the displaced surface: one refinement is far below a micrometre for mm bumps.
    const Plane shifted{plane.normal, plane.offset - Displacement(local)};
    if (const auto t2 = IntersectRayPlane(ray, shifted, 1e-6)) hit = ray.At(*t2);
    local = Local(hit);
  }
  const Eigen::Vector3d n = SurfaceNormal(local);
  return Ray3d{hit, (ray.direction - 2.0 * n.dot(ray.direction) * n).normalized()};
}

Eigen::Vector3d Mirror::ImageOf(const Eigen::Vector3d& point, const Eigen::Vector3d& eye) const {
  Eigen::Vector3d image = plane.ReflectPoint(point);
  if (bump_mm == 0.0) return image;
  // Fixed point: the mirror point the eye sees the image through, the surface's tangent
  // plane there, the point reflected in it. Millimetre bumps over a 620 mm mirror tilt it
  // by milliradians, so a few rounds settle far below a micrometre.
  for (int round = 0; round < 8; ++round) {
    const Ray3d sight{eye, (image - eye).normalized()};
    const auto t = IntersectRayPlane(sight, plane, 1e-6);
    if (!t) return image;
    const Eigen::Vector2d local = Local(sight.At(*t));
    const Eigen::Vector3d normal = SurfaceNormal(local);
    const Eigen::Vector3d on_surface = sight.At(*t) + Displacement(local) * plane.normal;
    const Plane tangent{normal, -normal.dot(on_surface)};
    image = tangent.ReflectPoint(point);
  }
  return image;
}

std::array<Eigen::Vector3d, 4> Mirror::Corners() const {
  return {origin, origin + width * along, origin + width * along + height * up,
          origin + height * up};
}

namespace {

TriangleMesh Quad(const Eigen::Vector3d& origin, const Eigen::Vector3d& along,
                  const Eigen::Vector3d& up, double width, double height,
                  const Eigen::Vector3d& front_normal) {
  TriangleMesh mesh;
  mesh.vertices = {origin, origin + width * along, origin + width * along + height * up,
                   origin + height * up};
  // Wind counter-clockwise as seen from the front.
  if (along.cross(up).dot(front_normal) > 0) {
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  } else {
    mesh.triangles = {{0, 2, 1}, {0, 3, 2}};
  }
  return mesh;
}

}  // namespace

TriangleMesh Mirror::Mesh() const { return Quad(origin, along, up, width, height, plane.normal); }

TriangleMesh Panel::Mesh() const { return Quad(origin, along, up, width, height, plane.normal); }

double Sensor::BlurAt(double distance_mm) const {
  if (!Defocused() || !(distance_mm > 0)) return blur_px;
  const double defocus =
      defocus_px_per_diopter * std::abs(1000.0 / distance_mm - 1000.0 / focus_mm);
  return std::hypot(blur_px, defocus);
}

Scene Scene::Load(const std::filesystem::path& file) {
  const nlohmann::json json = JsonReader::ParseFile(file);
  return Parse(json, file.string(), file.parent_path());
}

Scene Scene::Parse(const nlohmann::json& json, const std::string& file_name,
                   const std::filesystem::path& base_dir) {
  const JsonReader root(json, file_name);
  root.AllowOnly({"cameras", "mirrors", "panels", "floor", "lasers", "sensor", "subject", "target",
                  "chessboard", "frames", "seed"});
  Scene scene;

  // Cameras.
  nlohmann::json cameras_json = DefaultCameras();
  if (root.Has("cameras")) cameras_json = json["cameras"];
  const nlohmann::json wrapper = {{"cameras", cameras_json}};
  const JsonReader cameras_reader(root.Has("cameras") ? json : wrapper, file_name);
  const auto camera_readers = cameras_reader.Objects("cameras");
  if (camera_readers.empty() || camera_readers.size() > kMaxCameras) {
    root.Fail("cameras", "expected one to " + std::to_string(kMaxCameras) + " cameras");
  }
  for (const auto& r : camera_readers) scene.cameras.push_back(ParseCamera(r));
  for (size_t i = 1; i < scene.cameras.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (scene.cameras[i].name == scene.cameras[j].name) {
        root.Fail("cameras", "camera names must differ");
      }
    }
    if (scene.cameras[i].fps != scene.cameras[0].fps) {
      root.Fail("cameras", "all cameras must run at the same fps");
    }
  }

  // Mirrors, 120° apart by default, meeting at a vertical corner line behind the subject;
  // sized for people 1.45-2.05 m (docs/cabinet-design.md).
  const nlohmann::json empty = nlohmann::json::object();
  const JsonReader mr(json.contains("mirrors") ? json["mirrors"] : empty, file_name, "mirrors");
  mr.AllowOnly({"width_mm", "height_mm", "bottom_mm", "angle_deg", "corner_y_mm", "reflectivity",
                "left_bump_mm", "right_bump_mm"});
  const double width = mr.Number("width_mm", 1000.0, 50.0, 5000.0);
  const double height = mr.Number("height_mm", 2100.0, 50.0, 5000.0);
  const double bottom = mr.Number("bottom_mm", 0.0, 0.0, 3000.0);
  const double angle = mr.Number("angle_deg", 120.0, 60.0, 179.0) * kDeg;
  const double corner_y = mr.Number("corner_y_mm", 900.0, 100.0, 5000.0);
  const double reflectivity = mr.Number("reflectivity", 0.9, 0.0, 1.0);
  const double phi = (std::numbers::pi - angle) / 2.0;  // each mirror's turn from the x axis
  const Eigen::Vector3d corner(0.0, corner_y, bottom);
  for (int side = 0; side < 2; ++side) {
    const double sign = side == 0 ? -1.0 : 1.0;
    Mirror& m = scene.mirrors[side];
    m.name = side == 0 ? "left" : "right";
    m.origin = corner;
    m.along = Eigen::Vector3d(sign * std::cos(phi), -std::sin(phi), 0.0);
    m.up = Eigen::Vector3d::UnitZ();
    m.plane =
        Plane::FromPointNormal(corner, Eigen::Vector3d(-sign * std::sin(phi), -std::cos(phi), 0.0));
    m.width = width;
    m.height = height;
    m.reflectivity = reflectivity;
    m.bump_mm = mr.Number(side == 0 ? "left_bump_mm" : "right_bump_mm", 0.0, -20.0, 20.0);
  }

  const JsonReader pr(json.contains("panels") ? json["panels"] : empty, file_name, "panels");
  pr.AllowOnly({"offset_mm", "left_offset_mm", "right_offset_mm", "margin_mm", "albedo"});
  const double common_offset = pr.Number("offset_mm", 6.0, 0.0, 200.0);
  const double margin = pr.Number("margin_mm", 120.0, 10.0, 2000.0);
  const double panel_albedo = pr.Number("albedo", 0.8, 0.0, 1.0);
  for (int side = 0; side < 2; ++side) {
    const Mirror& m = scene.mirrors[side];
    Panel& p = scene.panels[side];
    // A panel mounted off its nominal place (what the laser calibration must notice).
    const double offset =
        pr.Number(side == 0 ? "left_offset_mm" : "right_offset_mm", common_offset, 0.0, 200.0);
    p.name = m.name;
    p.offset_mm = offset;
    p.plane = Plane{m.plane.normal, m.plane.offset + offset};  // `offset` further from the subject
    p.along = m.along;
    p.up = m.up;
    p.origin = m.origin - offset * m.plane.normal - Eigen::Vector3d(0, 0, bottom);
    p.width = width + margin;
    p.height = bottom + height + margin;
    p.albedo = panel_albedo;
  }

  const JsonReader fr(json.contains("floor") ? json["floor"] : empty, file_name, "floor");
  fr.AllowOnly({"albedo"});
  scene.floor_albedo = fr.Number("albedo", 0.25, 0.0, 1.0);

  const JsonReader lr(json.contains("lasers") ? json["lasers"] : empty, file_name, "lasers");
  lr.AllowOnly({"count", "spacing_mm", "start_mm", "speed_mm_s", "sheet_sigma_mm", "tilt_deg",
                "emitter_mm", "emitters_mm", "power", "fan_deg"});
  Lasers& lasers = scene.lasers;
  lasers.count = lr.Integer("count", 3, 1, 3);
  lasers.spacing_mm = lr.Number("spacing_mm", 200.0, 20.0, 2000.0);
  lasers.start_mm = lr.Number("start_mm", -50.0, -3000.0, 3000.0);
  lasers.speed_mm_s = lr.Number("speed_mm_s", 150.0, 1.0, 5000.0);
  lasers.sheet_sigma_mm = lr.Number("sheet_sigma_mm", 1.0, 0.05, 20.0);
  const auto tilt = lr.Numbers("tilt_deg", 2, std::vector<double>{0.0, 0.0});
  if (std::abs(tilt[0]) > 10 || std::abs(tilt[1]) > 10) lr.Fail("tilt_deg", "must be within ±10°");
  lasers.normal =
      (Eigen::AngleAxisd(tilt[0] * kDeg, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(tilt[1] * kDeg, Eigen::Vector3d::UnitY()) * Eigen::Vector3d::UnitZ())
          .normalized();
  if (lr.Has("emitter_mm") && lr.Has("emitters_mm")) {
    lr.Fail("emitters_mm", "give emitter_mm (one emitter) or emitters_mm (a list), not both");
  }
  if (lr.Has("emitters_mm")) {
    const nlohmann::json& list = json["lasers"]["emitters_mm"];
    if (!list.is_array() || list.empty() || list.size() > 8) {
      lr.Fail("emitters_mm", "expected a list of 1 to 8 [x, y] positions");
    }
    lasers.emitters_xy.clear();
    for (const nlohmann::json& xy : list) {
      if (!xy.is_array() || xy.size() != 2 || !xy[0].is_number() || !xy[1].is_number()) {
        lr.Fail("emitters_mm", "each emitter is [x, y] in mm");
      }
      lasers.emitters_xy.emplace_back(xy[0].get<double>(), xy[1].get<double>());
    }
  } else if (lr.Has("emitter_mm")) {
    const auto emitter = lr.Numbers("emitter_mm", 2);
    lasers.emitters_xy = {{emitter[0], emitter[1]}};
  }
  for (const Mirror& m : scene.mirrors) {
    if (m.bump_mm != 0.0 && lasers.emitters_xy.size() > 1) {
      lr.Fail("emitters_mm",
              "a bumped mirror's light is modelled from one emitter only (give "
              "lasers.emitter_mm)");
    }
  }
  lasers.power = lr.Number("power", 2.0, 0.0, 100.0);
  lasers.fan_deg = lr.Number("fan_deg", 90.0, 1.0, 360.0);

  const JsonReader sr(json.contains("sensor") ? json["sensor"] : empty, file_name, "sensor");
  sr.AllowOnly({"ambient_dn", "laser_dn", "read_noise_dn", "electrons_per_dn", "speckle_contrast",
                "blur_px", "focus_mm", "defocus_px_per_diopter", "noise"});
  Sensor& sensor = scene.sensor;
  sensor.ambient_dn = sr.Number("ambient_dn", 40.0, 0.0, 255.0);
  sensor.laser_dn = sr.Number("laser_dn", 400.0, 0.0, 1e5);
  sensor.read_noise_dn = sr.Number("read_noise_dn", 2.0, 0.0, 100.0);
  sensor.electrons_per_dn = sr.Number("electrons_per_dn", 40.0, 0.01, 1e6);
  sensor.speckle_contrast = sr.Number("speckle_contrast", 0.2, 0.0, 1.0);
  sensor.blur_px = sr.Number("blur_px", 0.7, 0.0, 10.0);
  sensor.focus_mm = sr.Number("focus_mm", 0.0, 0.0, 1e5);
  sensor.defocus_px_per_diopter = sr.Number("defocus_px_per_diopter", 0.0, 0.0, 100.0);
  if (sensor.defocus_px_per_diopter > 0 && !(sensor.focus_mm > 0)) {
    sr.Fail("focus_mm", "must be > 0 when defocus_px_per_diopter is set");
  }
  sensor.noise = sr.Bool("noise", true);

  // "albedo" is the renderer's business; the rest describes the subject's shape.
  nlohmann::json subject_json = {{"type", "mannequin"}};
  if (json.contains("subject")) subject_json = json["subject"];
  if (subject_json.is_object() && subject_json.contains("albedo")) {
    if (subject_json.value("type", "") == "body") {
      JsonReader(subject_json, file_name, "subject")
          .Fail("albedo",
                "a body's albedo is per region: skin_albedo, hair_albedo, underwear_albedo");
    }
    scene.subject_albedo =
        JsonReader(subject_json, file_name, "subject").Number("albedo", 0.6, 0.0, 1.0);
    subject_json.erase("albedo");
  }
  // So is "light_spread" (subsurface scattering, e.g. skin).
  if (subject_json.is_object() && subject_json.contains("light_spread")) {
    const JsonReader spread = JsonReader(subject_json, file_name, "subject").Object("light_spread");
    spread.AllowOnly({"sigma_mm", "tail_mm"});
    scene.subject_light_spread.sigma_mm = spread.Number("sigma_mm", 0.0, 0.0, 20.0);
    scene.subject_light_spread.tail_mm = spread.Number("tail_mm", 0.0, -20.0, 20.0);
    subject_json.erase("light_spread");
  }
  scene.subject = ParseSubject(JsonReader(subject_json, file_name, "subject"), base_dir);

  if (json.contains("target") && !json["target"].is_null()) {
    scene.target.emplace(TargetConfig::Parse(JsonReader(json["target"], file_name, "target")));
  }
  if (json.contains("chessboard") && !json["chessboard"].is_null()) {
    scene.chessboard.emplace(
        ChessboardConfig::Parse(JsonReader(json["chessboard"], file_name, "chessboard")));
  }
  scene.frames = root.Integer("frames", 350, 1, 100000);
  const double seed = root.Number("seed", 1.0, 0.0, 9.0e15);
  if (seed != std::floor(seed)) root.Fail("seed", "expected a whole number");
  scene.seed = static_cast<uint64_t>(seed);
  return scene;
}

nlohmann::json Scene::TrueCalibration() const {
  // The schema's own writer (common/config/calibration), so the truth is always a file
  // the calibration tools read.
  Calibration truth;
  truth.source = "virtual cabinet ground truth";
  truth.target_id = target ? "virtual-3panel-aruco48" : "";
  for (const auto& c : cameras) {
    CalibrationCamera camera;
    camera.name = c.name;
    camera.camera = c.camera;
    camera.fps = c.fps;
    camera.views.push_back({"center", std::nullopt, {}});
    for (const auto& m : mirrors) {
      // The mirror's outline in the image: everything inside is seen through it.
      CalibrationView view{m.name, m.name, {}};
      const auto corners = m.Corners();
      for (int edge = 0; edge < 4; ++edge) {
        for (int i = 0; i < 16; ++i) {
          const Eigen::Vector3d p =
              corners[edge] + (corners[(edge + 1) % 4] - corners[edge]) * (i / 16.0);
          if (const auto px = c.camera.ProjectWorld(p)) view.outline_px.push_back(*px);
        }
      }
      camera.views.push_back(view);
    }
    truth.cameras.push_back(camera);
  }
  for (int i = 0; i < 2; ++i) {
    const Mirror& m = mirrors[i];
    const auto corners = m.Corners();
    truth.mirrors.push_back(
        {m.name, m.plane, {corners.begin(), corners.end()}, panels[i].offset_mm});
  }
  CalibrationLasers truth_lasers;
  truth_lasers.count = lasers.count;
  truth_lasers.spacing_mm = lasers.spacing_mm;
  truth_lasers.normal = lasers.normal;
  truth_lasers.height_at_t0_mm = lasers.start_mm;
  truth_lasers.speed_mm_s = lasers.speed_mm_s;
  truth.lasers = truth_lasers;
  return truth.ToJson();
}

}  // namespace mirrorscan::virtual_cabinet

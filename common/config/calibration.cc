#include "common/config/calibration.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <set>

#include <Eigen/Geometry>

namespace mirrorscan {

namespace {

// Unit vectors and rotations written with 17 significant digits are unit and orthonormal
// far inside this; anything outside was edited or corrupted.
constexpr double kUnitTolerance = 1e-6;

nlohmann::json Vec(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

Eigen::Vector3d Vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

Eigen::Vector3d UnitVector(const JsonReader& r, const std::string& key) {
  const Eigen::Vector3d v = Vec3(r.Numbers(key, 3));
  if (std::abs(v.norm() - 1.0) > kUnitTolerance) r.Fail(key, "must be a unit vector");
  return v.normalized();
}

// A 3x3 array of finite numbers.
Eigen::Matrix3d Matrix3(const JsonReader& r, const std::string& key) {
  if (!r.Has(key)) r.Fail(key, "missing (expected a 3x3 array)");
  const nlohmann::json& rows = r.value()[key];
  Eigen::Matrix3d m;
  if (!rows.is_array() || rows.size() != 3) r.Fail(key, "expected a 3x3 array of numbers");
  for (int i = 0; i < 3; ++i) {
    const nlohmann::json& row = rows[i];
    if (!row.is_array() || row.size() != 3) r.Fail(key, "expected a 3x3 array of numbers");
    for (int j = 0; j < 3; ++j) {
      if (!row[j].is_number() || !std::isfinite(row[j].get<double>())) {
        r.Fail(key, "expected a 3x3 array of finite numbers");
      }
      m(i, j) = row[j].get<double>();
    }
  }
  return m;
}

std::vector<Eigen::Vector2d> Points2(const JsonReader& r, const std::string& key) {
  const nlohmann::json& a = r.value()[key];
  if (!a.is_array()) r.Fail(key, "expected an array of [u, v] pixels");
  std::vector<Eigen::Vector2d> points;
  for (const auto& p : a) {
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number() ||
        !std::isfinite(p[0].get<double>()) || !std::isfinite(p[1].get<double>())) {
      r.Fail(key, "expected an array of [u, v] pixels (finite numbers)");
    }
    points.emplace_back(p[0].get<double>(), p[1].get<double>());
  }
  return points;
}

std::vector<Eigen::Vector3d> Points3(const JsonReader& r, const std::string& key) {
  const nlohmann::json& a = r.value()[key];
  if (!a.is_array()) r.Fail(key, "expected an array of [x, y, z] points");
  std::vector<Eigen::Vector3d> points;
  for (const auto& p : a) {
    if (!p.is_array() || p.size() != 3) r.Fail(key, "expected an array of [x, y, z] points");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) {
      if (!p[i].is_number() || !std::isfinite(p[i].get<double>())) {
        r.Fail(key, "expected an array of [x, y, z] points (finite numbers)");
      }
      v[i] = p[i].get<double>();
    }
    points.push_back(v);
  }
  return points;
}

CalibrationCamera ParseCamera(const JsonReader& r) {
  r.AllowOnly({"name", "width", "height", "fps", "K", "distortion", "cam_from_world", "views"});
  CalibrationCamera c;
  c.name = r.String("name");
  if (c.name.empty()) r.Fail("name", "must not be empty");
  CameraIntrinsics& k = c.camera.intrinsics;
  k.width = r.Integer("width", std::nullopt, 16, 16384);
  k.height = r.Integer("height", std::nullopt, 16, 16384);
  c.fps = r.Number("fps", 30.0, 0.1, 1000.0);
  const Eigen::Matrix3d K = Matrix3(r, "K");
  if (K(0, 1) != 0.0 || K(1, 0) != 0.0 || K(2, 0) != 0.0 || K(2, 1) != 0.0 || K(2, 2) != 1.0) {
    r.Fail("K", "expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]");
  }
  k.fx = K(0, 0), k.fy = K(1, 1), k.cx = K(0, 2), k.cy = K(1, 2);
  if (k.fx < 1.0 || k.fy < 1.0 || k.fx > 1e6 || k.fy > 1e6)
    r.Fail("K", "fx, fy must be in [1, 1e6]");
  if (std::abs(k.cx) > 2.0 * k.width || std::abs(k.cy) > 2.0 * k.height) {
    r.Fail("K", "principal point far outside the image");
  }
  const auto d = r.Numbers("distortion", 5);
  for (double x : d) {
    if (std::abs(x) > 10) r.Fail("distortion", "coefficients must be within ±10");
  }
  k.k1 = d[0], k.k2 = d[1], k.p1 = d[2], k.p2 = d[3], k.k3 = d[4];

  const JsonReader pose = r.Object("cam_from_world");
  pose.AllowOnly({"rotation", "translation_mm"});
  const Eigen::Matrix3d R = Matrix3(pose, "rotation");
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kUnitTolerance ||
      R.determinant() < 0.0) {
    pose.Fail("rotation", "must be a proper rotation (orthonormal, determinant +1)");
  }
  const Eigen::Vector3d t = Vec3(pose.Numbers("translation_mm", 3));
  if (t.cwiseAbs().maxCoeff() > 1e6) pose.Fail("translation_mm", "beyond 1 km");
  c.camera.cam_from_world = Rigid3d(Eigen::Quaterniond(R), t);

  std::set<std::string> view_names;
  for (const JsonReader& vr : r.Objects("views")) {
    vr.AllowOnly({"name", "mirror", "outline_px"});
    CalibrationView v;
    v.name = vr.String("name");
    if (v.name.empty()) vr.Fail("name", "must not be empty");
    if (!view_names.insert(v.name).second) vr.Fail("name", "duplicate view \"" + v.name + "\"");
    if (vr.Has("mirror")) {
      v.mirror = vr.String("mirror");
      if (!vr.Has("outline_px")) vr.Fail("outline_px", "missing (a mirror view needs its region)");
      v.outline_px = Points2(vr, "outline_px");
      if (v.outline_px.size() < 3) vr.Fail("outline_px", "needs at least 3 points");
    } else if (vr.Has("outline_px")) {
      vr.Fail("outline_px", "only mirror views have an outline (the centre is the rest)");
    }
    c.views.push_back(std::move(v));
  }
  int centre_views = 0;
  for (const auto& v : c.views) centre_views += v.mirror ? 0 : 1;
  if (centre_views != 1) r.Fail("views", "expected exactly one view without a mirror (the centre)");
  return c;
}

CalibrationMirror ParseMirror(const JsonReader& r) {
  r.AllowOnly({"name", "normal", "offset_mm", "corners_mm", "panel_offset_mm"});
  CalibrationMirror m;
  m.name = r.Choice("name", {"left", "right"});
  m.plane.normal = UnitVector(r, "normal");
  m.plane.offset = r.Number("offset_mm", std::nullopt, -1e5, 1e5);
  if (r.Has("corners_mm")) {
    m.corners_mm = Points3(r, "corners_mm");
    if (m.corners_mm.size() != 4) r.Fail("corners_mm", "expected 4 corners");
    for (const auto& c : m.corners_mm) {
      if (std::abs(m.plane.SignedDistance(c)) > 1.0) {
        r.Fail("corners_mm", "corners must lie in the mirror plane (within 1 mm)");
      }
    }
  }
  m.panel_offset_mm = r.Number("panel_offset_mm", 0.0, 0.0, 1000.0);
  return m;
}

CalibrationLasers ParseLasers(const JsonReader& r) {
  r.AllowOnly({"count", "spacing_mm", "normal", "height_at_t0_mm", "speed_mm_s", "offsets_mm",
               "readback_offset_mm", "note"});
  CalibrationLasers l;
  l.count = r.Integer("count", std::nullopt, 1, 16);
  l.spacing_mm = r.Number("spacing_mm", std::nullopt, 0.0, 1e4);
  l.normal = UnitVector(r, "normal");
  l.height_at_t0_mm = r.Number("height_at_t0_mm", std::nullopt, -1e5, 1e5);
  l.speed_mm_s = r.Number("speed_mm_s", std::nullopt, -1e5, 1e5);
  if (r.Has("offsets_mm")) {
    l.offsets_mm = r.Numbers("offsets_mm", static_cast<size_t>(l.count));
    if (l.offsets_mm[0] != 0.0) r.Fail("offsets_mm", "must start with laser 0's own offset, 0");
    for (size_t k = 1; k < l.offsets_mm.size(); ++k) {
      if (!(l.offsets_mm[k] > l.offsets_mm[k - 1]) || l.offsets_mm[k] > 1e5)
        r.Fail("offsets_mm", "lasers must be ordered upwards along the slide, within 100 m");
    }
  }
  if (r.Has("readback_offset_mm"))
    l.readback_offset_mm = r.Number("readback_offset_mm", std::nullopt, -1e5, 1e5);
  return l;
}

CalibrationResiduals ParseResiduals(const JsonReader& r) {
  r.AllowOnly({"reprojection_rms_px", "views"});
  CalibrationResiduals res;
  res.reprojection_rms_px = r.Number("reprojection_rms_px", std::nullopt, 0.0, 1e6);
  if (r.Has("views")) {
    for (const JsonReader& vr : r.Objects("views")) {
      vr.AllowOnly({"camera", "view", "rms_px", "max_px", "points"});
      res.views.push_back(
          {vr.String("camera"), vr.String("view"), vr.Number("rms_px", std::nullopt, 0.0, 1e6),
           vr.Number("max_px", std::nullopt, 0.0, 1e6), vr.Integer("points", std::nullopt, 0)});
    }
  }
  return res;
}

}  // namespace

bool CalibrationView::Contains(const Eigen::Vector2d& pixel) const {
  // Even–odd rule.
  bool inside = false;
  const size_t n = outline_px.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = outline_px[i];
    const Eigen::Vector2d& b = outline_px[j];
    if ((a.y() > pixel.y()) != (b.y() > pixel.y()) &&
        pixel.x() < (b.x() - a.x()) * (pixel.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

const CalibrationView* CalibrationCamera::ViewAt(const Eigen::Vector2d& pixel) const {
  const CalibrationView* centre = nullptr;
  for (const auto& v : views) {
    if (!v.mirror) {
      centre = &v;
    } else if (v.Contains(pixel)) {
      return &v;
    }
  }
  return centre;
}

Calibration Calibration::Parse(const nlohmann::json& json, const std::string& file_name) {
  const JsonReader root(json, file_name);
  root.AllowOnly({"schema", "version", "source", "target_id", "content_hash", "cameras", "mirrors",
                  "lasers", "residuals"});
  if (root.String("schema") != kCalibrationSchema) {
    root.Fail("schema", std::string("expected \"") + kCalibrationSchema + "\"");
  }
  const int version = root.Integer("version");
  if (version != kCalibrationVersion) {
    root.Fail("version", "unsupported version " + std::to_string(version) + " (this build reads " +
                             std::to_string(kCalibrationVersion) + ")");
  }
  Calibration c;
  c.source = root.String("source", "");
  c.target_id = root.String("target_id", "");

  const auto mirror_readers = root.Objects("mirrors");
  if (mirror_readers.size() != 2) root.Fail("mirrors", "expected two mirrors, left and right");
  for (const auto& r : mirror_readers) c.mirrors.push_back(ParseMirror(r));
  if (c.mirrors[0].name == c.mirrors[1].name) root.Fail("mirrors", "mirror names must differ");

  const auto camera_readers = root.Objects("cameras");
  if (camera_readers.empty() || camera_readers.size() > kMaxCameras) {
    root.Fail("cameras", "expected one to " + std::to_string(kMaxCameras) + " cameras");
  }
  for (const auto& r : camera_readers) {
    c.cameras.push_back(ParseCamera(r));
    for (const auto& v : c.cameras.back().views) {
      if (v.mirror && !c.FindMirror(*v.mirror)) {
        r.Fail("views", "view \"" + v.name + "\" names unknown mirror \"" + *v.mirror + "\"");
      }
    }
  }
  for (size_t i = 1; i < c.cameras.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (c.cameras[i].name == c.cameras[j].name) root.Fail("cameras", "camera names must differ");
    }
  }
  if (root.Has("lasers")) c.lasers = ParseLasers(root.Object("lasers"));
  c.residuals = ParseResiduals(root.Object("residuals"));

  if (root.Has("content_hash") && root.String("content_hash") != c.ContentHash()) {
    root.Fail("content_hash", "does not match the contents (file edited or corrupted)");
  }
  return c;
}

Calibration Calibration::Load(const std::filesystem::path& file) {
  return Parse(JsonReader::ParseFile(file), file.string());
}

Calibration Calibration::ParseText(const std::string& text, const std::string& file_name) {
  return Parse(JsonReader::ParseText(text, file_name), file_name);
}

namespace {

nlohmann::json GeometryJson(const Calibration& c) {
  nlohmann::json cameras = nlohmann::json::array();
  for (const auto& cam : c.cameras) {
    const CameraIntrinsics& k = cam.camera.intrinsics;
    const Eigen::Matrix3d r = cam.camera.cam_from_world.RotationMatrix();
    nlohmann::json views = nlohmann::json::array();
    for (const auto& v : cam.views) {
      nlohmann::json view = {{"name", v.name}};
      view["mirror"] = v.mirror ? nlohmann::json(*v.mirror) : nlohmann::json(nullptr);
      if (v.mirror) {
        nlohmann::json outline = nlohmann::json::array();
        for (const auto& p : v.outline_px) outline.push_back({p.x(), p.y()});
        view["outline_px"] = outline;
      }
      views.push_back(view);
    }
    cameras.push_back({{"name", cam.name},
                       {"width", k.width},
                       {"height", k.height},
                       {"fps", cam.fps},
                       {"K", {{k.fx, 0.0, k.cx}, {0.0, k.fy, k.cy}, {0.0, 0.0, 1.0}}},
                       {"distortion", {k.k1, k.k2, k.p1, k.p2, k.k3}},
                       {"cam_from_world",
                        {{"rotation",
                          {{r(0, 0), r(0, 1), r(0, 2)},
                           {r(1, 0), r(1, 1), r(1, 2)},
                           {r(2, 0), r(2, 1), r(2, 2)}}},
                         {"translation_mm", Vec(cam.camera.cam_from_world.translation)}}},
                       {"views", views}});
  }
  nlohmann::json mirrors = nlohmann::json::array();
  for (const auto& m : c.mirrors) {
    nlohmann::json mirror = {{"name", m.name},
                             {"normal", Vec(m.plane.normal)},
                             {"offset_mm", m.plane.offset},
                             {"panel_offset_mm", m.panel_offset_mm}};
    if (!m.corners_mm.empty()) {
      nlohmann::json corners = nlohmann::json::array();
      for (const auto& p : m.corners_mm) corners.push_back(Vec(p));
      mirror["corners_mm"] = corners;
    }
    mirrors.push_back(mirror);
  }
  nlohmann::json json = {{"schema", kCalibrationSchema},
                         {"version", kCalibrationVersion},
                         {"target_id", c.target_id},
                         {"cameras", cameras},
                         {"mirrors", mirrors}};
  if (c.lasers) {
    json["lasers"] = {{"count", c.lasers->count},
                      {"spacing_mm", c.lasers->spacing_mm},
                      {"normal", Vec(c.lasers->normal)},
                      {"height_at_t0_mm", c.lasers->height_at_t0_mm},
                      {"speed_mm_s", c.lasers->speed_mm_s}};
    if (!c.lasers->offsets_mm.empty()) json["lasers"]["offsets_mm"] = c.lasers->offsets_mm;
    if (c.lasers->readback_offset_mm)
      json["lasers"]["readback_offset_mm"] = *c.lasers->readback_offset_mm;
  }
  return json;
}

}  // namespace

namespace {

// Numbers printed with 10 significant digits, so the last-bit changes of reading a file
// back (rotation matrix to quaternion and back, renormalised normals) keep the hash.
nlohmann::json Canonical(const nlohmann::json& json) {
  if (json.is_number_float()) {
    const double x = json.get<double>();
    char text[32];
    std::snprintf(text, sizeof text, "%.10g", std::abs(x) < 1e-9 ? 0.0 : x);
    return text;
  }
  if (json.is_array() || json.is_object()) {
    nlohmann::json out = json;
    for (auto& item : out) item = Canonical(item);
    return out;
  }
  return json;
}

}  // namespace

std::string Calibration::ContentHash() const {
  // Keys are sorted in the dump, so the text is canonical.
  const std::string text = Canonical(GeometryJson(*this)).dump();
  uint64_t hash = 0xcbf29ce484222325ULL;
  for (unsigned char ch : text) {
    hash ^= ch;
    hash *= 0x100000001b3ULL;
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
  return hex;
}

nlohmann::json Calibration::ToJson() const {
  nlohmann::json json = GeometryJson(*this);
  json["source"] = source;
  json["content_hash"] = ContentHash();
  nlohmann::json views = nlohmann::json::array();
  for (const auto& v : residuals.views) {
    views.push_back({{"camera", v.camera},
                     {"view", v.view},
                     {"rms_px", v.rms_px},
                     {"max_px", v.max_px},
                     {"points", v.points}});
  }
  json["residuals"] = {{"reprojection_rms_px", residuals.reprojection_rms_px}, {"views", views}};
  return json;
}

const CalibrationCamera* Calibration::FindCamera(const std::string& name) const {
  for (const auto& c : cameras) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

const CalibrationMirror* Calibration::FindMirror(const std::string& name) const {
  for (const auto& m : mirrors) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

}  // namespace mirrorscan

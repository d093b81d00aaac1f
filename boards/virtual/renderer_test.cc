#include "boards/virtual/renderer.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace mirrorscan::virtual_cabinet {
namespace {

std::string ScenePath(const std::string& name) {
  return std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/" + name + ".json";
}

// Renderers cache per-camera work; share them across tests.
const Renderer& SharedRenderer(const std::string& name, bool noise = true) {
  static std::map<std::string, std::unique_ptr<Renderer>> renderers;
  const std::string key = name + (noise ? "" : "/noise-free");
  auto& r = renderers[key];
  if (!r) {
    Scene scene = Scene::Load(ScenePath(name));
    scene.sensor.noise = noise;
    r = std::make_unique<Renderer>(scene);
  }
  return *r;
}

cv::Mat ToMat(const GrayImage& image) {
  return cv::Mat(image.height, image.width, CV_8U, const_cast<uint8_t*>(image.pixels.data()))
      .clone();
}

Eigen::Vector3d Reflect(const Scene& scene, View view, Eigen::Vector3d point) {
  const auto path = MirrorPath(view);
  for (auto it = path.rbegin(); it != path.rend(); ++it)
    point = scene.mirrors[*it].plane.ReflectPoint(point);
  return point;
}

double PointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Distance to the plane when the projection falls inside, else to the nearest edge.
  const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
  const Eigen::Vector3d q = p - n.dot(p - a) * n;
  const bool inside = n.dot((b - a).cross(q - a)) >= 0 && n.dot((c - b).cross(q - b)) >= 0 &&
                      n.dot((a - c).cross(q - c)) >= 0;
  if (inside) return std::abs(n.dot(p - a));
  auto segment = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
    const double t = std::clamp((p - x).dot(y - x) / (y - x).squaredNorm(), 0.0, 1.0);
    return (p - (x + t * (y - x))).norm();
  };
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

// The cuboid's box from its metadata: signed distance to its surface.
double BoxDistance(const Scene& scene, const Eigen::Vector3d& p) {
  const auto& m = scene.subject.metadata;
  const Eigen::Vector3d center(m["center_mm"][0], m["center_mm"][1], m["center_mm"][2]);
  const Eigen::Vector3d half =
      0.5 * Eigen::Vector3d(m["size_mm"][0], m["size_mm"][1], m["size_mm"][2]);
  const double yaw = m.value("yaw_deg", 0.0) * M_PI / 180.0;
  const Eigen::Vector3d local = Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()) * (p - center);
  const Eigen::Vector3d q = local.cwiseAbs() - half;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

// The default cabinet as docs/virtual-cabinet.md states it, restated here so that the
// truth is checked against the scene's numbers and OpenCV's projection, not against the
// renderer's own planes, reflections and camera model (which made the truth).
constexpr double kLaserStartMm = -50.0, kLaserSpeedMmS = 150.0, kLaserSpacingMm = 200.0;
constexpr double kMirrorCornerYMm = 900.0, kMirrorAngleDeg = 120.0;

double LaserHeightMm(int laser, double t) {
  return kLaserStartMm + kLaserSpeedMmS * t + laser * kLaserSpacingMm;
}

// Mirror `side` (0 left, 1 right): a vertical plane through the corner line, turned
// (180° - angle)/2 from the x axis, normal towards the subject.
Eigen::Vector3d MirrorNormal(int side) {
  const double phi = (180.0 - kMirrorAngleDeg) / 2.0 * M_PI / 180.0;
  return {side == 0 ? std::sin(phi) : -std::sin(phi), -std::cos(phi), 0.0};
}

Eigen::Vector3d ReflectInMirror(int side, const Eigen::Vector3d& p) {
  const Eigen::Vector3d n = MirrorNormal(side);
  return p - 2.0 * n.dot(p - Eigen::Vector3d(0, kMirrorCornerYMm, 0)) * n;
}

// The virtual point the camera sees: the ray meets `path`'s mirrors in order, so the
// point is reflected in the last one first.
Eigen::Vector3d MirrorImage(View view, Eigen::Vector3d p) {
  std::vector<int> path;
  if (view == View::kLeft || view == View::kLeftRight) path.push_back(0);
  if (view == View::kRight || view == View::kRightLeft) path.push_back(1);
  if (view == View::kLeftRight) path.push_back(1);
  if (view == View::kRightLeft) path.push_back(0);
  for (auto it = path.rbegin(); it != path.rend(); ++it) p = ReflectInMirror(*it, p);
  return p;
}

// A default camera (f 1150 px, centred principal point, the default distortion) looking
// from `position` at `look_at` with world z up, projected by cv::projectPoints.
cv::Point2d ProjectWithOpenCv(const Eigen::Vector3d& position, const Eigen::Vector3d& look_at,
                              const Eigen::Vector3d& point) {
  const Eigen::Vector3d forward = (look_at - position).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  cv::Matx33d rotation;  // rows: the camera's x (right), y (down), z (forward) in world
  for (int j = 0; j < 3; ++j) {
    rotation(0, j) = right[j];
    rotation(1, j) = down[j];
    rotation(2, j) = forward[j];
  }
  cv::Vec3d rvec;
  cv::Rodrigues(rotation, rvec);
  const cv::Vec3d p(position.x(), position.y(), position.z());
  const cv::Vec3d tvec = -(rotation * p);
  const cv::Matx33d k(1150, 0, 511.5, 0, 1150, 383.5, 0, 0, 1);
  const std::vector<double> distortion = {-0.08, 0.05, 3e-4, -2e-4, 0.0};
  std::vector<cv::Point2d> pixels;
  cv::projectPoints(std::vector<cv::Point3d>{{point.x(), point.y(), point.z()}}, rvec, tvec, k,
                    distortion, pixels);
  return pixels[0];
}

// The default cameras: upper (0) and lower (1).
cv::Point2d ProjectInDefaultCamera(int camera, const Eigen::Vector3d& point) {
  return camera == 0 ? ProjectWithOpenCv({0, -1800, 2400}, {0, 300, 1550}, point)
                     : ProjectWithOpenCv({0, -1800, 1350}, {0, 300, 450}, point);
}

TEST(RendererTest, TruthPointsLieOnLaserPlaneAndSurfaceAndProjectToTheirPixel) {
  const Renderer& renderer = SharedRenderer("cuboid");
  const Scene& scene = renderer.scene();
  const double t = 6.3;  // laser 2 near the cuboid's middle (z ≈ 1295 mm)
  const auto peaks = renderer.Truth(0, t);
  std::map<View, int> on_box;
  std::map<int, int> per_laser;
  const TriangleMesh& mesh = scene.subject.mesh;
  const Eigen::Vector3d mirror_corner(0, kMirrorCornerYMm, 0);
  for (const TruthPeak& p : peaks) {
    ASSERT_LT(std::abs(p.point_in_world.z() - LaserHeightMm(p.laser, t)), 1e-6);
    ++per_laser[p.laser];
    const cv::Point2d pixel = ProjectInDefaultCamera(0, MirrorImage(p.view, p.point_in_world));
    ASSERT_LT(std::abs(pixel.x - p.u), 0.01) << ViewName(p.view);
    ASSERT_LT(std::abs(pixel.y - p.v), 0.01) << ViewName(p.view);
    if (p.material == Material::kPanel) {
      // Panels stand 6 mm behind their mirror (further from the subject).
      const int side = p.point_in_world.x() < 0 ? 0 : 1;
      EXPECT_NEAR(MirrorNormal(side).dot(p.point_in_world - mirror_corner), -6.0, 1e-6);
    } else if (p.material == Material::kSubject) {
      double nearest = 1e9;
      for (const auto& tri : mesh.triangles) {
        nearest =
            std::min(nearest, PointTriangleDistance(p.point_in_world, mesh.vertices[tri[0]],
                                                    mesh.vertices[tri[1]], mesh.vertices[tri[2]]));
      }
      ASSERT_LT(nearest, 1e-3);
      if (std::abs(BoxDistance(scene, p.point_in_world)) < 1.0) {
        EXPECT_LT(std::abs(BoxDistance(scene, p.point_in_world)), 1e-3);
        ++on_box[p.view];
      }
    }
  }
  // All three lines are in the frame; the laser ring: the cuboid is seen lit directly and
  // through both mirrors.
  EXPECT_GT(per_laser[0], 100);
  EXPECT_GT(per_laser[1], 100);
  EXPECT_GT(per_laser[2], 100);
  EXPECT_GT(on_box[View::kCenter], 100);
  EXPECT_GT(on_box[View::kLeft], 50);
  EXPECT_GT(on_box[View::kRight], 50);
}

TEST(RendererTest, TruthFollowsTiltedLaserPlanes) {
  Scene scene = Scene::Load(ScenePath("cylinder"));
  const Eigen::Vector3d normal =
      (Eigen::AngleAxisd(1.5 * M_PI / 180, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(-0.8 * M_PI / 180, Eigen::Vector3d::UnitY()) * Eigen::Vector3d::UnitZ());
  scene.lasers.normal = normal;
  const Renderer renderer(scene);
  const double t = 5.0;
  const auto peaks = renderer.Truth(1, t);
  int on_cylinder = 0;
  for (const TruthPeak& p : peaks) {
    // Laser k's sheet: normal · x = start + speed·t + k·spacing.
    ASSERT_LT(std::abs(normal.dot(p.point_in_world) - LaserHeightMm(p.laser, t)), 1e-6);
    const cv::Point2d pixel = ProjectInDefaultCamera(1, MirrorImage(p.view, p.point_in_world));
    ASSERT_LT(std::hypot(pixel.x - p.u, pixel.y - p.v), 0.01) << ViewName(p.view);
    if (p.material == Material::kSubject) {
      // On the cylinder's side (radius 150 about the z axis) or a cap (z 400, 1400).
      const double r = std::hypot(p.point_in_world.x(), p.point_in_world.y());
      ASSERT_TRUE(std::abs(r - 150.0) < 0.01 || std::abs(p.point_in_world.z() - 400.0) < 1e-6 ||
                  std::abs(p.point_in_world.z() - 1400.0) < 1e-6)
          << "r " << r << " z " << p.point_in_world.z();
      ++on_cylinder;
    }
  }
  // A tilted sheet cuts the cylinder in a tilted ellipse: its height varies around it.
  double z_min = 1e9, z_max = -1e9;
  for (const TruthPeak& p : peaks) {
    if (p.material != Material::kSubject || p.laser != 1) continue;
    z_min = std::min(z_min, p.point_in_world.z());
    z_max = std::max(z_max, p.point_in_world.z());
  }
  EXPECT_GT(on_cylinder, 300);
  EXPECT_GT(z_max - z_min, 3.0);
}

struct DetectedMarker {
  int id;
  std::array<cv::Point2f, 4> corners;
};

std::vector<DetectedMarker> Detect(const cv::Mat& image, bool flip) {
  cv::Mat input = image;
  if (flip) cv::flip(image, input = cv::Mat(), 1);  // a new buffer: never flip `image` in place
  auto dictionary = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  auto parameters = cv::aruco::DetectorParameters::create();
  parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  parameters->cornerRefinementWinSize = 4;
  parameters->cornerRefinementMinAccuracy = 0.001;
  parameters->cornerRefinementMaxIterations = 100;
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(input, dictionary, corners, ids, parameters);
  std::vector<DetectedMarker> result;
  for (size_t i = 0; i < ids.size(); ++i) {
    DetectedMarker m{ids[i], {}};
    for (int c = 0; c < 4; ++c) {
      cv::Point2f p = corners[i][c];
      if (flip) p.x = static_cast<float>(image.cols - 1) - p.x;
      m.corners[c] = p;
    }
    result.push_back(m);
  }
  return result;
}

// How far a marker's rendered corners lie from where projection puts them. Each border
// is measured in the image independently of any corner detector (whose corners are biased
// on blurred images): per image column or row across it, the centroid of the intensity
// differences over the blurred step, compared with where the projected border crosses
// that column or row. A corner's displacement follows from the mean offsets of its two
// borders. nullopt when a border runs too close to the image edge.
std::optional<std::array<Eigen::Vector2d, 4>> CornerDisplacements(
    const cv::Mat& image, const Scene& scene, int camera, View view,
    const std::array<Eigen::Vector3d, 4>& corners) {
  const Camera& cam = scene.cameras[camera].camera;
  auto project = [&](const Eigen::Vector3d& p) {
    return *cam.ProjectWorld(Reflect(scene, view, p));
  };
  std::array<double, 4> offsets;           // mean offset along each border's image normal
  std::array<Eigen::Vector2d, 4> normals;  // unit image normals of the borders
  for (int edge = 0; edge < 4; ++edge) {
    const Eigen::Vector3d& a3 = corners[edge];
    const Eigen::Vector3d& b3 = corners[(edge + 1) % 4];
    const Eigen::Vector2d a = project(a3), b = project(b3);
    const bool along_u = std::abs(b.x() - a.x()) > std::abs(b.y() - a.y());
    const int major = along_u ? 0 : 1, minor = 1 - major;
    const Eigen::Vector2d direction = (b - a).normalized();
    normals[edge] = Eigen::Vector2d(-direction.y(), direction.x());
    const double lo = std::min(a[major], b[major]), hi = std::max(a[major], b[major]);
    double sum = 0;
    int n = 0;
    for (int m = static_cast<int>(std::ceil(lo + 0.15 * (hi - lo))); m <= hi - 0.15 * (hi - lo);
         ++m) {
      // Where the projected border (curved by distortion) crosses this column or row.
      double f_lo = 0, f_hi = 1;
      for (int i = 0; i < 50; ++i) {
        const double f = 0.5 * (f_lo + f_hi);
        ((project(a3 + f * (b3 - a3))[major] < m) == (b[major] > a[major]) ? f_lo : f_hi) = f;
      }
      const double predicted = project(a3 + f_lo * (b3 - a3))[minor];
      const int c0 = static_cast<int>(std::lround(predicted));
      if (c0 < 6 || c0 > (along_u ? image.rows : image.cols) - 7) return std::nullopt;
      auto at = [&](int c) {
        return static_cast<double>(along_u ? image.at<uint8_t>(c, m) : image.at<uint8_t>(m, c));
      };
      double weight = 0, moment = 0;
      for (int c = c0 - 4; c < c0 + 4; ++c) {
        weight += at(c + 1) - at(c);
        moment += (at(c + 1) - at(c)) * (c + 0.5);
      }
      if (std::abs(weight) < 20) continue;
      sum += moment / weight - predicted;
      ++n;
    }
    if (n < 10) return std::nullopt;
    // An offset along the minor axis moves the border by that times |normal[minor]|.
    offsets[edge] = sum / n * std::abs(normals[edge][minor]) * (normals[edge][minor] > 0 ? 1 : -1);
  }
  std::array<Eigen::Vector2d, 4> displacements;
  for (int c = 0; c < 4; ++c) {
    const int before = (c + 3) % 4;
    Eigen::Matrix2d n;
    n.row(0) = normals[before].transpose();
    n.row(1) = normals[c].transpose();
    displacements[c] = n.inverse() * Eigen::Vector2d(offsets[before], offsets[c]);
  }
  return displacements;
}

// The right mirror's bumped surface, from the scene file's numbers
// (docs/virtual-cabinet.md): 1000 x 2100 mm from the floor at the corner line, displaced
// along its normal by bump (1 - a²)(1 - b²), a, b in [-1, 1] across width and height.
struct BumpedRightMirror {
  double bump_mm;
  static constexpr double kWidth = 1000.0, kHeight = 2100.0, kBottom = 0.0;
  Eigen::Vector3d corner{0.0, kMirrorCornerYMm, kBottom};
  Eigen::Vector3d normal = MirrorNormal(1);
  Eigen::Vector3d along = Eigen::Vector3d::UnitZ().cross(MirrorNormal(1));  // outwards, +x

  // The surface point at (a mm along, z) and its unit normal there.
  std::pair<Eigen::Vector3d, Eigen::Vector3d> At(double a_mm, double z) const {
    const double a = 2.0 * a_mm / kWidth - 1.0, b = 2.0 * (z - kBottom) / kHeight - 1.0;
    const double displacement = bump_mm * (1 - a * a) * (1 - b * b);
    const double d_da = bump_mm * (-2 * a) * (2 / kWidth) * (1 - b * b);
    const double d_db = bump_mm * (1 - a * a) * (-2 * b) * (2 / kHeight);
    const Eigen::Vector3d n =
        (normal - d_da * along - d_db * Eigen::Vector3d::UnitZ()).normalized();
    return {
        corner + a_mm * along + (z - kBottom) * Eigen::Vector3d::UnitZ() + displacement * normal,
        n};
  }
};

// Where the level sheet at height h, sent from the emitter (0, -900, h) to the bumped
// mirror at `a_mm` along it, meets the cylinder of the cylinder scene (radius 150 about
// the z axis) after the reflection; nullopt if it misses.
struct LitSpot {
  Eigen::Vector3d point;
  double cosine;  // between the light and the cylinder's normal there
};
std::optional<LitSpot> BumpedLightOnCylinder(const BumpedRightMirror& mirror, double h,
                                             double a_mm) {
  const Eigen::Vector3d emitter(0.0, -900.0, h);
  const auto [on_mirror, n] = mirror.At(a_mm, h);
  const Eigen::Vector3d in = (on_mirror - emitter).normalized();
  const Eigen::Vector3d out = in - 2.0 * n.dot(in) * n;
  // |xy(on_mirror + s out)| = 150.
  const Eigen::Vector2d p = on_mirror.head<2>(), d = out.head<2>();
  const double qa = d.squaredNorm(), qb = 2.0 * p.dot(d), qc = p.squaredNorm() - 150.0 * 150.0;
  const double disc = qb * qb - 4.0 * qa * qc;
  if (disc < 0) return std::nullopt;
  const double s = (-qb - std::sqrt(disc)) / (2.0 * qa);
  if (s <= 0) return std::nullopt;
  const Eigen::Vector3d point = on_mirror + s * out;
  const Eigen::Vector3d radial(point.x() / 150.0, point.y() / 150.0, 0.0);
  return LitSpot{point, -radial.dot(out)};
}

double SegmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& x,
                       const Eigen::Vector3d& y) {
  const double t = std::clamp((p - x).dot(y - x) / (y - x).squaredNorm(), 0.0, 1.0);
  return (p - (x + t * (y - x))).norm();
}

// Light reaching the body through a bumped mirror follows the real surface: the sheet
// leaves the mirror at its local normal and is bent out of its plane. Every truth point
// off the laser's own plane lies on the bent sheet as computed here from the mirror's
// formula (not the renderer's Mirror), and the rendered frame is lit there.
TEST(RendererTest, LightThroughABumpedMirrorFollowsItsSurface) {
  Scene scene = Scene::Load(ScenePath("cylinder"));
  scene.lasers.count = 1;
  scene.lasers.emitters_xy = {{0.0, -900.0}};  // a bumped mirror's light from one emitter
  scene.sensor.noise = false;
  const double bump_mm = 3.0;
  scene.mirrors[1].bump_mm = bump_mm;
  const Renderer renderer(scene);
  const BumpedRightMirror mirror{bump_mm};
  const double t = 5.0;
  const double h = LaserHeightMm(0, t);  // 700 mm, on the cylinder
  std::vector<LitSpot> curve;            // the bent sheet on the cylinder, along the mirror
  // Fine steps: where the light grazes the cylinder, its spot moves far per step.
  for (double a = 0.0; a <= BumpedRightMirror::kWidth; a += 0.002) {
    if (const auto p = BumpedLightOnCylinder(mirror, h, a)) curve.push_back(*p);
  }
  ASSERT_GT(curve.size(), 100u);
  int bent = 0, lit = 0, grazing = 0;
  double worst = 0.0, largest_bend = 0.0;
  for (int camera = 0; camera < 2; ++camera) {
    const FloatImage on = renderer.RenderRadiance(camera, t, true);
    const FloatImage off = renderer.RenderRadiance(camera, t, false);
    for (const TruthPeak& p : renderer.Truth(camera, t)) {
      const double bend = p.point_in_world.z() - h;
      if (std::abs(bend) < 1e-6) continue;  // the sheet's own plane: direct or flat mirror
      ASSERT_EQ(p.material, Material::kSubject);
      double nearest = 1e9, cosine = 1.0;
      for (size_t i = 1; i < curve.size(); ++i) {
        const Eigen::Vector3d &a = curve[i - 1].point, &b = curve[i].point;
        if ((b - a).norm() > 5.0) continue;  // not across a gap in the curve
        const double d = SegmentDistance(p.point_in_world, a, b);
        if (d < nearest) {
          nearest = d;
          cosine = curve[i].cosine;
        }
      }
      // Where the light grazes the surface its spot on the mesh's 0.5° facets and on the
      // true cylinder part by the facets' sagitta over the cosine: not a rendering error.
      if (cosine < 0.15) {
        ++grazing;
        continue;
      }
      EXPECT_LT(nearest, 0.05) << "camera " << camera << " " << ViewName(p.view) << " u " << p.u
                               << " point " << p.point_in_world.transpose() << " bend " << bend;
      worst = std::max(worst, nearest);
      largest_bend = std::max(largest_bend, std::abs(bend));
      ++bent;
      const int v = static_cast<int>(std::lround(p.v));
      float light = 0.0f;
      for (int r = std::max(v - 1, 0); r <= std::min(v + 1, on.height - 1); ++r)
        light = std::max(light, on.at(p.u, r) - off.at(p.u, r));
      lit += light > 5.0f;
    }
  }
  std::printf(
      "bent sheet: %d truth points (and %d grazing), worst %.4f mm from the analytic "
      "sheet, bend up to %.2f mm, %d lit in the frame\n",
      bent, grazing, worst, largest_bend, lit);
  EXPECT_GT(bent, 100);
  EXPECT_GT(largest_bend, 1.5);  // far off the flat plane: the bend matters
  EXPECT_GE(lit, bent * 95 / 100);
}

// What a camera sees of the mannequin through the mirrors between the hips and the
// chest (z 950-1250 mm): pixels (every 3rd row and column) per part, by the subject's
// part triangle ranges (metadata "parts").
std::map<std::string, int> MirrorViewPartsAtTheTorso(const Renderer& renderer, int camera) {
  const nlohmann::json& parts = renderer.scene().subject.metadata.at("parts");
  std::map<std::string, int> counts;
  {
    for (int v = 0; v < 768; v += 3) {
      for (int u = 0; u < 1024; u += 3) {
        const SurfaceSample s = renderer.TracePixel(camera, {u, v});
        if (s.material != Material::kSubject || (s.view != View::kLeft && s.view != View::kRight))
          continue;
        if (s.hit.point.z() < 950.0 || s.hit.point.z() > 1250.0) continue;
        for (const nlohmann::json& part : parts) {
          const int first = part.at("first_triangle"), count = part.at("triangle_count");
          if (s.hit.triangle >= first && s.hit.triangle < first + count)
            ++counts[part.at("name").get<std::string>()];
        }
      }
    }
  }
  return counts;
}

// Both poses happen: the A-pose's hanging arms stand between the mirrors and the torso's
// sides and back; in mannequin-arms-raised.json no arm is in the mirror views at the
// torso's heights. (The raised arms hide some of the torso from the upper camera's steep
// mirror views, while the lower camera sees more of it: measured and printed here.)
TEST(RendererTest, RaisedArmsLeaveTheMirrorViewsAtTheTorsosHeights) {
  int hanging_arms_seen = 0, torso_seen = 0;
  for (int camera = 0; camera < 2; ++camera) {
    std::map<std::string, int> hanging =
        MirrorViewPartsAtTheTorso(SharedRenderer("mannequin"), camera);
    std::map<std::string, int> raised =
        MirrorViewPartsAtTheTorso(SharedRenderer("mannequin-arms-raised"), camera);
    const int hanging_arms = hanging["left_arm"] + hanging["right_arm"];
    const int raised_arms = raised["left_arm"] + raised["right_arm"];
    std::printf(
        "camera %d, mirror views at z 950-1250 mm: A-pose torso %d, arms %d px; arms "
        "raised torso %d, arms %d px\n",
        camera, hanging["torso"], hanging_arms, raised["torso"], raised_arms);
    hanging_arms_seen += hanging_arms;
    torso_seen += hanging["torso"];
    EXPECT_EQ(raised_arms, 0) << camera;
  }
  EXPECT_GT(hanging_arms_seen, torso_seen / 10);  // the hanging arms hide part of it
}

TEST(RendererTest, MarkerCornersRenderWhereProjectionPredicts) {
  const Renderer& renderer = SharedRenderer("calibration", /*noise=*/false);
  const Scene& scene = renderer.scene();
  ASSERT_TRUE(scene.target);
  for (int camera = 0; camera < static_cast<int>(scene.cameras.size()); ++camera) {
    const cv::Mat image = ToMat(renderer.RenderFrame(camera, 0.0, 0, /*lasers_on=*/false));
    std::map<View, std::vector<double>> errors;
    for (bool flip : {false, true}) {
      for (const DetectedMarker& m : Detect(image, flip)) {
        cv::Point2f middle(0, 0);
        for (const auto& c : m.corners) middle += 0.25f * c;
        const View seen_in = renderer.TracePixel(camera, {middle.x, middle.y}).view;
        // A whole-image flip also mirrors the direct view, where a mirrored marker may
        // decode as another id: only mirror regions are read flipped.
        if (flip != (seen_in == View::kLeft || seen_in == View::kRight)) continue;
        // Panel 0 faces the camera; panel 1 is seen in the left mirror, panel 2 in the right.
        const int panel = m.id / 16;
        const View view = panel == 0 ? View::kCenter : panel == 1 ? View::kLeft : View::kRight;
        ASSERT_EQ(seen_in, view) << "marker " << m.id << " found in the wrong view";
        const auto& truth = scene.target->markers()[m.id].corners;
        // The detector's corners only locate the marker (they sit ~0.2 px inside on a
        // blurred image); the borders are then measured against projection.
        for (int c = 0; c < 4; ++c) {
          const auto expected =
              scene.cameras[camera].camera.ProjectWorld(Reflect(scene, view, truth[c]));
          ASSERT_TRUE(expected);
          ASSERT_LT(std::hypot(m.corners[c].x - expected->x(), m.corners[c].y - expected->y()),
                    1.0);
        }
        const auto displacements = CornerDisplacements(image, scene, camera, view, truth);
        if (!displacements) continue;  // too close to the image border to measure
        for (const auto& d : *displacements) errors[view].push_back(d.norm());
      }
    }
    for (View view : {View::kCenter, View::kLeft, View::kRight}) {
      const auto& e = errors[view];
      ASSERT_GE(e.size(), 4u * 4) << "camera " << camera << " view " << ViewName(view);
      double sum2 = 0;
      for (double x : e) sum2 += x * x;
      const double rms = std::sqrt(sum2 / e.size());
      // 0.05 px when the mirrors' markers were 10 % larger in the image (f 1400 px, the
      // mirrors 300 mm nearer); the edge fit's own error grows as they shrink, and as they
      // are foreshortened: the camera looking up from 300 mm sees the target's centre
      // panel 28 degrees from below (0.067 px).
      const double bound = camera == 2 && view == View::kCenter ? 0.075 : 0.06;
      EXPECT_LT(*std::max_element(e.begin(), e.end()), bound)
          << "camera " << camera << " view " << ViewName(view);
      std::printf("camera %d view %-6s: %zu corners, RMS %.4f px, max %.4f px\n", camera,
                  ViewName(view), e.size(), rms, *std::max_element(e.begin(), e.end()));
    }
  }
}

TEST(RendererTest, ViewThroughAMirrorIsMirrorImaged) {
  const Renderer& renderer = SharedRenderer("calibration", /*noise=*/false);
  const cv::Mat image = ToMat(renderer.RenderFrame(0, 0.0, 0, /*lasers_on=*/false));
  // Markers of the back panels read correctly (right id, where that marker is) only in
  // the flipped image. (Unflipped, a mirrored marker can decode as some other id.)
  const Scene& scene = renderer.scene();
  std::map<std::pair<bool, View>, int> readable;  // (flipped, view) -> markers read correctly
  for (bool flip : {false, true}) {
    for (const DetectedMarker& m : Detect(image, flip)) {
      const View view = m.id / 16 == 1   ? View::kLeft
                        : m.id / 16 == 2 ? View::kRight
                                         : View::kCenter;
      if (view == View::kCenter) continue;
      bool in_place = true;
      for (int c = 0; c < 4; ++c) {
        const auto expected = scene.cameras[0].camera.ProjectWorld(
            Reflect(scene, view, scene.target->markers()[m.id].corners[c]));
        in_place = in_place && expected &&
                   std::hypot(m.corners[c].x - expected->x(), m.corners[c].y - expected->y()) < 1.0;
      }
      if (in_place) ++readable[{flip, view}];
    }
  }
  EXPECT_EQ((readable[{false, View::kLeft}]), 0);
  EXPECT_EQ((readable[{false, View::kRight}]), 0);
  EXPECT_GE((readable[{true, View::kLeft}]), 4);
  EXPECT_GE((readable[{true, View::kRight}]), 4);
  // And geometrically: moving right along an image row in the left mirror, the surface
  // point seen moves the other way along the target's back-left panel.
  const auto& panel = renderer.scene().target->panels()[1];
  const auto& corners = renderer.scene().target->markers()[24].corners;
  const Eigen::Vector3d middle = 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
  const auto pixel = renderer.scene().cameras[0].camera.ProjectWorld(
      renderer.scene().mirrors[0].plane.ReflectPoint(middle));
  ASSERT_TRUE(pixel);
  const SurfaceSample a = renderer.TracePixel(0, *pixel),
                      b = renderer.TracePixel(0, *pixel + Eigen::Vector2d(5, 0));
  ASSERT_EQ(a.view, View::kLeft);
  ASSERT_EQ(b.view, View::kLeft);
  EXPECT_LT((b.hit.point - a.hit.point).dot(panel.right), 0);
}

TEST(RendererTest, NoiseFreeStripeCentroidMatchesTruthRow) {
  const Renderer& renderer = SharedRenderer("cuboid", /*noise=*/false);
  double sum2 = 0, sum = 0;
  int n = 0;
  for (double t : {5.5, 6.3, 7.0}) {  // stripes across the cuboid's faces
    const cv::Mat on = ToMat(renderer.RenderFrame(0, t, 7, true));
    const cv::Mat off = ToMat(renderer.RenderFrame(0, t, 7, false));
    const auto peaks = renderer.Truth(0, t);
    std::map<int, std::vector<double>> rows_by_column;
    for (const auto& p : peaks) rows_by_column[p.u].push_back(p.v);
    for (const auto& p : peaks) {
      // Planar faces only: on a thin curved tube the stripe bends within one column, so a
      // column's centroid and the curve's crossing differ by geometry, not by rendering.
      if (p.material != Material::kSubject || p.peak_dn < 60 ||
          std::abs(BoxDistance(renderer.scene(), p.point_in_world)) > 1e-3) {
        continue;
      }
      bool isolated = true;
      for (double v : rows_by_column[p.u])
        isolated = isolated && (v == p.v || std::abs(v - p.v) > 10);
      const int v0 = static_cast<int>(std::lround(p.v));
      if (!isolated || v0 < 5 || v0 >= on.rows - 5) continue;
      double weight = 0, moment = 0;
      for (int v = v0 - 4; v <= v0 + 4; ++v) {
        const double value = on.at<uint8_t>(v, p.u) - off.at<uint8_t>(v, p.u);
        weight += value;
        moment += value * v;
      }
      if (weight <= 0) continue;
      const double error = moment / weight - p.v;
      sum += error;
      sum2 += error * error;
      ++n;
    }
  }
  ASSERT_GT(n, 500);
  const double rms = std::sqrt(sum2 / n);
  std::printf("stripe centroid vs truth over %d columns: RMS %.4f px, bias %.4f px\n", n, rms,
              sum / n);
  EXPECT_LT(rms, 0.05);
  EXPECT_LT(std::abs(sum / n), 0.01);
}

// Mean and variance (rows) of the laser light (lasers on minus off, noise-free) in column
// u within ±12 rows of row v.
std::pair<double, double> LightMoments(const FloatImage& lit, const FloatImage& dark, int u,
                                       double v) {
  double sum = 0, moment = 0, moment2 = 0;
  const int centre = static_cast<int>(std::lround(v));
  for (int r = centre - 12; r <= centre + 12; ++r) {
    const double light = lit.at(u, r) - dark.at(u, r);
    sum += light;
    moment += light * r;
    moment2 += light * r * r;
  }
  const double mean = moment / sum;
  return {mean, moment2 / sum - mean * mean};
}

// Truth peaks on the cuboid's flat faces, centre view, away from other stripes and image
// edges, on stripes with |slope| < 0.1 (so the blur along u does not widen the column).
std::vector<TruthPeak> FlatFacePeaks(const Renderer& renderer, int camera, double t) {
  const auto truth = renderer.Truth(camera, t);
  std::map<int, std::vector<const TruthPeak*>> by_column;
  for (const auto& p : truth) by_column[p.u].push_back(&p);
  std::vector<TruthPeak> out;
  for (const auto& p : truth) {
    if (p.material != Material::kSubject || p.view != View::kCenter || p.peak_dn < 60 ||
        std::abs(BoxDistance(renderer.scene(), p.point_in_world)) > 1e-3 || p.v < 20 || p.v > 748) {
      continue;
    }
    bool alone = true, left = false, right = false;
    for (const TruthPeak* q : by_column[p.u])
      alone = alone && (q == &p || std::abs(q->v - p.v) > 25);
    for (int side : {-1, 1}) {
      for (const TruthPeak* q : by_column[p.u + side]) {
        if (q->laser == p.laser && q->view == p.view && std::abs(q->v - p.v) < 0.1) {
          (side < 0 ? left : right) = true;
        }
      }
    }
    if (alone && left && right) out.push_back(p);
  }
  return out;
}

// Defocus: the blur grows with the dioptres off the focal plane, Gaussians add in
// quadrature, so a stripe's column variance grows by exactly (k |1/d - 1/d_f|)² px², d the
// camera-to-surface distance from the scene's geometry.
TEST(RendererTest, DefocusWidensStripesAsTheThinLensPredicts) {
  Scene sharp = Scene::Load(ScenePath("cuboid"));
  sharp.sensor.noise = false;
  Scene blurred = sharp;
  blurred.sensor.focus_mm = 1500;
  blurred.sensor.defocus_px_per_diopter = 9;
  const Renderer a(sharp), b(blurred);
  const Eigen::Vector3d centre = sharp.cameras[0].camera.CenterInWorld();
  int n = 0;
  double worst = 0;
  for (double t : {5.5, 6.3, 7.0}) {
    const FloatImage a_lit = a.RenderRadiance(0, t), a_dark = a.RenderRadiance(0, t, false);
    const FloatImage b_lit = b.RenderRadiance(0, t), b_dark = b.RenderRadiance(0, t, false);
    for (const TruthPeak& p : FlatFacePeaks(a, 0, t)) {
      const double d = (p.point_in_world - centre).norm();
      const double defocus = 9 * std::abs(1000 / d - 1000 / 1500.0);
      const double grown = LightMoments(b_lit, b_dark, p.u, p.v).second -
                           LightMoments(a_lit, a_dark, p.u, p.v).second;
      worst = std::max(worst, std::abs(grown / (defocus * defocus) - 1));
      ++n;
    }
  }
  ASSERT_GT(n, 300);
  std::printf("defocus: column variance grew as predicted to within %.1f %% (%d columns)\n",
              100 * worst, n);
  EXPECT_LT(worst, 0.03);
}

// Skin's light spread on the subject: the sheet (sigma 1 mm) convolved with a Gaussian of
// sigma_mm and a one-sided exponential of tail_mm. Moments add: the column variance grows
// by (sigma_mm² + tail_mm²) g² and the centre moves by tail_mm g towards +w (up: smaller
// rows), g the px per mm along the laser normal, known from the sharp stripe's variance
// (sheet² g² + blur² + 1/12 for the pixel). Panels spread nothing.
TEST(RendererTest, SkinLightSpreadBroadensAndShiftsAsItsMomentsPredict) {
  Scene plain = Scene::Load(ScenePath("cuboid"));
  plain.sensor.noise = false;
  Scene skin = plain;
  skin.subject_light_spread = {2.0, 1.0};
  const Renderer a(plain), b(skin);
  const double blur = plain.sensor.blur_px, sheet = plain.lasers.sheet_sigma_mm;
  int n = 0;
  double worst_width = 0, worst_shift = 0;
  for (double t : {5.5, 6.3, 7.0}) {
    const FloatImage a_lit = a.RenderRadiance(0, t), a_dark = a.RenderRadiance(0, t, false);
    const FloatImage b_lit = b.RenderRadiance(0, t), b_dark = b.RenderRadiance(0, t, false);
    for (const TruthPeak& p : FlatFacePeaks(a, 0, t)) {
      const auto [a_mean, a_var] = LightMoments(a_lit, a_dark, p.u, p.v);
      const auto [b_mean, b_var] = LightMoments(b_lit, b_dark, p.u, p.v);
      const double g2 = (a_var - blur * blur - 1.0 / 12) / (sheet * sheet);
      worst_width = std::max(worst_width, std::abs((b_var - a_var) / (5.0 * g2) - 1));
      worst_shift = std::max(worst_shift, std::abs((a_mean - b_mean) / std::sqrt(g2) - 1));
      ++n;
    }
    // Panel pixels are rendered exactly as without the spread.
    const auto truth = a.Truth(0, t);
    for (const TruthPeak& p : truth) {
      if (p.material != Material::kPanel || p.v < 15 || p.v > 752) continue;
      bool near_subject = false;
      for (const TruthPeak& q : truth) {
        near_subject = near_subject || (q.material == Material::kSubject &&
                                        std::abs(q.u - p.u) <= 3 && std::abs(q.v - p.v) < 40);
      }
      if (near_subject) continue;
      for (int r = static_cast<int>(p.v) - 12; r <= static_cast<int>(p.v) + 12; ++r)
        ASSERT_EQ(a_lit.at(p.u, r), b_lit.at(p.u, r)) << p.u << " " << r;
    }
  }
  ASSERT_GT(n, 300);
  std::printf("skin: variance within %.1f %%, shift within %.1f %% (%d columns)\n",
              100 * worst_width, 100 * worst_shift, n);
  EXPECT_LT(worst_width, 0.02);
  EXPECT_LT(worst_shift, 0.02);
}

// The lens blurs the continuous image before pixels integrate it, so a stripe's column
// profile is the same shape at every sub-pixel phase. In the mirror views a pixel spans
// ~3 mm of a 1 mm sheet; blurring pixel means with a sampled kernel made the shape depend
// on the phase, and a 3-point Gaussian then erred by up to 0.07 px there.
TEST(RendererTest, MirrorStripeProfileShapeDoesNotDependOnPhase) {
  const Renderer& renderer = SharedRenderer("cuboid", /*noise=*/false);
  std::vector<double> errors;
  for (double t : {5.5, 6.3, 7.0}) {
    const FloatImage on = renderer.RenderRadiance(0, t, true);
    const FloatImage off = renderer.RenderRadiance(0, t, false);
    const auto peaks = renderer.Truth(0, t);
    std::map<int, std::vector<double>> rows_by_column;
    for (const auto& p : peaks) rows_by_column[p.u].push_back(p.v);
    for (const auto& p : peaks) {
      if ((p.view != View::kLeft && p.view != View::kRight) || p.material != Material::kSubject ||
          p.peak_dn < 40 || std::abs(BoxDistance(renderer.scene(), p.point_in_world)) > 1e-3) {
        continue;
      }
      bool isolated = true;
      for (double v : rows_by_column[p.u])
        isolated = isolated && (v == p.v || std::abs(v - p.v) > 10);
      int k = static_cast<int>(std::lround(p.v));
      if (!isolated || k < 5 || k >= on.height - 5) continue;
      auto laser = [&](int v) { return on.at(p.u, v) - off.at(p.u, v); };
      if (laser(k + 1) > laser(k)) ++k;
      if (laser(k - 1) > laser(k)) --k;
      const double a = laser(k - 1), b = laser(k), c = laser(k + 1);
      if (!(a > 0 && c > 0)) continue;
      const double v = k + 0.5 * std::log(a / c) / std::log(a * c / (b * b));
      errors.push_back(std::abs(v - p.v));
    }
  }
  ASSERT_GT(errors.size(), 200u);
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2], p90 = errors[errors.size() * 9 / 10];
  std::printf(
      "mirror stripes, 3-point Gaussian on the float image over %zu columns: median "
      "%.4f px, p90 %.4f px\n",
      errors.size(), median, p90);
  EXPECT_LT(median, 0.002);  // 0.03 with the sampled blur kernel
  EXPECT_LT(p90, 0.005);
}

// Laser light is known analytically in a cabinet whose mirrors reflect nothing: each
// sheet is horizontal and comes straight from its emitter at (0, -900) mm, so a point on
// the sheet is lit exactly when it faces the emitter and the segment to it misses the
// subject. A short upright cylinder stands beside the line from the emitter to the middle
// of the right panel's outer margin (the strip beside the mirror that the camera sees
// directly), tangent to it: in the sheet that crosses the cylinder the part of the
// margin further out lies in its shadow and the part further in is lit; the sheets above
// it light the whole margin. Every point is projected with cv::projectPoints, not traced.
// With several emitters (`emitters`, the first at (0, -900)) a point is dark only where
// every emitter's segment to it meets the cylinder.
void CheckShadowsOfACylinder(const std::vector<Eigen::Vector2d>& emitters) {
  constexpr double kRadius = 60.0, kBottom = 400.0, kTop = 700.0;
  const Eigen::Vector2d emitter = emitters.front();
  const Eigen::Vector3d right_normal = MirrorNormal(1);
  const Eigen::Vector3d right_along(std::cos(M_PI / 6), -std::sin(M_PI / 6), 0.0);
  // The right panel 6 mm behind its mirror, from the corner line outwards.
  auto on_panel = [&](double along, double z) -> Eigen::Vector3d {
    return Eigen::Vector3d(0, kMirrorCornerYMm, z) - 6.0 * right_normal + along * right_along;
  };
  const Eigen::Vector2d margin_middle = on_panel(1040.0, 0.0).head<2>();
  const Eigen::Vector2d toward = (margin_middle - emitter).normalized();
  const Eigen::Vector2d outwards(toward.y(), -toward.x());  // towards larger `along`
  const Eigen::Vector2d centre = emitter + 650.0 * toward + kRadius * outwards;

  nlohmann::json json = {{"subject",
                          {{"type", "cylinder"},
                           {"radius_mm", kRadius},
                           {"bottom_mm", kBottom},
                           {"height_mm", kTop - kBottom},
                           {"center_mm", {centre.x(), centre.y()}}}},
                         {"mirrors", {{"reflectivity", 0.0}}},
                         {"sensor", {{"noise", false}}}};
  json["lasers"]["emitters_mm"] = nlohmann::json::array();
  for (const Eigen::Vector2d& e : emitters) json["lasers"]["emitters_mm"].push_back({e.x(), e.y()});
  json["lasers"]["fan_deg"] = 360;  // shadows, not fans: the panel's margin lies outside 90°
  const Renderer renderer(Scene::Parse(json, "shadow.json", "."));
  const double t = 4.0;  // laser 0 at 550 mm crosses the cylinder; lasers 1, 2 pass over it
  const cv::Mat on = ToMat(renderer.RenderFrame(1, t, 3, true));
  const cv::Mat off = ToMat(renderer.RenderFrame(1, t, 3, false));
  const Eigen::Vector3d camera_centre(0, -1800, 1350);  // the lower camera

  // Distance in the sheet from the cylinder's axis to the segment from p to an emitter;
  // the largest over the emitters (the one that sees p best).
  auto clearance = [&](const Eigen::Vector2d& p) {
    double best = 0;
    for (const Eigen::Vector2d& e : emitters) {
      const Eigen::Vector2d d = e - p;
      const double f = std::clamp((centre - p).dot(d) / d.squaredNorm(), 0.0, 1.0);
      best = std::max(best, (p + f * d - centre).norm());
    }
    return best;
  };
  auto pixel_of = [&](const Eigen::Vector3d& p) -> std::optional<cv::Point> {
    const cv::Point2d px = ProjectInDefaultCamera(1, p);
    const cv::Point rounded(static_cast<int>(std::lround(px.x)),
                            static_cast<int>(std::lround(px.y)));
    if (rounded.x < 3 || rounded.y < 3 || rounded.x >= on.cols - 3 || rounded.y >= on.rows - 3)
      return std::nullopt;
    return rounded;
  };
  auto lit_at = [&](cv::Point px) { return on.at<uint8_t>(px) > off.at<uint8_t>(px) + 10; };
  auto dark_around = [&](cv::Point px) {
    for (int dv = -2; dv <= 2; ++dv) {
      for (int du = -2; du <= 2; ++du) {
        const cv::Point q = px + cv::Point(du, dv);
        if (on.at<uint8_t>(q) != off.at<uint8_t>(q)) return false;
      }
    }
    return true;
  };

  std::map<std::string, int> counted;
  for (int laser = 0; laser < 3; ++laser) {
    const double z = LaserHeightMm(laser, t);
    for (double along = 1005.0; along <= 1075.0; along += 0.5) {
      const Eigen::Vector3d p = on_panel(along, z);
      // The camera looks at the margin over the cylinder's top.
      for (double f = 0; f <= 1.0; f += 0.001) {
        const Eigen::Vector3d q = p + f * (camera_centre - p);
        if ((q.head<2>() - centre).norm() <= kRadius) {
          ASSERT_GT(q.z(), kTop);
        }
      }
      const auto px = pixel_of(p);
      ASSERT_TRUE(px);
      const bool in_shadow = z < kTop && clearance(p.head<2>()) < kRadius;
      // The penumbra, and the shadow's edge within dark_around's ±2 px (~2 mm a pixel there).
      if (std::abs(clearance(p.head<2>()) - kRadius) < 5.0 && z < kTop) continue;
      if (in_shadow) {
        ++counted["panel hidden"];
        EXPECT_TRUE(dark_around(*px)) << "panel at " << along << " mm, laser " << laser;
      } else {
        ++counted["panel lit"];
        const Eigen::Vector2d d = emitter - p.head<2>();
        const double f = std::clamp((centre - p.head<2>()).dot(d) / d.squaredNorm(), 0.0, 1.0);
        if (z < kTop && (p.head<2>() + f * d - centre).norm() < kRadius - 3.0)
          ++counted["panel lit by another emitter"];
        EXPECT_TRUE(lit_at(*px)) << "panel at " << along << " mm, laser " << laser;
      }
    }
  }
  // The cylinder's side in sheet 0, where the camera sees it: lit where it faces the
  // emitter. (Its far side is in its own shade, but the camera, nearly behind the emitter,
  // sees only a sliver of that at the silhouette.)
  const double z = LaserHeightMm(0, t);
  for (double angle = 0; angle < 360.0; angle += 0.5) {
    const Eigen::Vector2d normal(std::cos(angle * M_PI / 180), std::sin(angle * M_PI / 180));
    const Eigen::Vector2d p = centre + kRadius * normal;
    const double facing_camera = normal.dot((camera_centre.head<2>() - p).normalized());
    const double facing_emitter = normal.dot((emitter - p).normalized());
    if (facing_camera < 0.2 || facing_emitter < 0.1) continue;
    const auto px = pixel_of(Eigen::Vector3d(p.x(), p.y(), z));
    if (!px) continue;
    ++counted["cylinder lit"];
    EXPECT_TRUE(lit_at(*px)) << "cylinder at " << angle << "°";
  }
  for (const auto& [what, n] : counted) std::printf("%s: %d points\n", what.c_str(), n);
  if (emitters.size() == 1) {
    EXPECT_GT(counted["panel hidden"], 30);
  }
  EXPECT_EQ(counted["panel lit by another emitter"] > 10, emitters.size() > 1);
  EXPECT_GT(counted["panel lit"], 200);
  EXPECT_GT(counted["cylinder lit"], 100);
}

TEST(RendererTest, PointHiddenFromTheLaserStaysDark) { CheckShadowsOfACylinder({{0.0, -900.0}}); }

// A second emitter on the slide (the same sheets) lights part of the first one's shadow.
TEST(RendererTest, ASecondEmitterLightsPartOfTheFirstOnesShadow) {
  CheckShadowsOfACylinder({{0.0, -900.0}, {600.0, -700.0}});
}

// An emitter behind the subject, in the mirrors' corner, aimed at the axis with a 90° fan:
// a point facing it is lit up to 45° off its aim and not beyond, and a point it reaches only
// by way of the right mirror (the light leaving it about 107° off its aim, towards the glass
// at (112, 835)) is dark; with the whole sheet lit (fan 360) that point is lit through the
// mirror. The angles are worked out from the scene's geometry, not by the renderer.
TEST(RendererTest, AnEmittersFanEndsAtItsEdges) {
  auto renderer_with_fan = [](double fan_deg) {
    const nlohmann::json json = {
        {"subject",
         {{"type", "cylinder"}, {"radius_mm", 5}, {"height_mm", 5}, {"center_mm", {0, -1500}}}},
        {"lasers", {{"emitters_mm", {{0, 800}}}, {"fan_deg", fan_deg}}},
        {"sensor", {{"noise", false}}}};
    return std::make_unique<Renderer>(Scene::Parse(json, "fan.json", "."));
  };
  const auto fan90 = renderer_with_fan(90);
  const auto fan360 = renderer_with_fan(360);
  const Eigen::Vector3d emitter(0, 800, 500);
  for (double deg : {-46.0, -44.0, 0.0, 44.0, 46.0}) {
    const double a = deg * M_PI / 180.0;
    const Eigen::Vector3d point = emitter + 500.0 * Eigen::Vector3d(std::sin(a), -std::cos(a), 0);
    const Eigen::Vector3d facing = (emitter - point).normalized();
    EXPECT_EQ(fan90->LaserIrradiance(point, facing) > 0, std::abs(deg) < 45) << deg << "°";
    EXPECT_GT(fan360->LaserIrradiance(point, facing), 0) << deg << "°";
  }
  // At (300, 0) facing (0.95, 0.31): the emitter lies behind that face's plane, its image in
  // the right mirror, (86, 949), in front of it; its image in the left one behind it.
  const Eigen::Vector3d point(300, 0, 500);
  const Eigen::Vector3d normal = Eigen::Vector3d(0.95, 0.31, 0).normalized();
  EXPECT_GT(fan360->LaserIrradiance(point, normal), 0);
  EXPECT_EQ(fan90->LaserIrradiance(point, normal), 0);
}

TEST(RendererTest, SameSeedSameFrameOtherFrameOtherNoise) {
  const Renderer& renderer = SharedRenderer("cylinder");
  const auto a = renderer.RenderFrame(0, 5.0, 150);
  const auto b = renderer.RenderFrame(0, 5.0, 150);
  const auto c = renderer.RenderFrame(0, 5.0, 151);
  EXPECT_EQ(a.pixels, b.pixels);
  EXPECT_NE(a.pixels, c.pixels);
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

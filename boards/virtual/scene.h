#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/chessboard.h"
#include "boards/virtual/mesh.h"
#include "boards/virtual/rendered_target.h"
#include "boards/virtual/subjects.h"
#include "common/geometry/camera.h"
#include "common/geometry/plane.h"

namespace mirrorscan::virtual_cabinet {

struct SceneCamera {
  std::string name;
  Camera camera;
  double fps = 30.0;
};

// A rectangular planar mirror, optionally with a smooth low-order bump (a cheap hall
// mirror): the surface is displaced along the normal by
//   bump_mm * (1 - a²)(1 - b²), a, b ∈ [-1, 1] across the width and height,
// which tilts the local normal and bends the reflected rays.
struct Mirror {
  std::string name;        // "left" or "right"
  Plane plane;             // normal towards the subject
  Eigen::Vector3d origin;  // bottom corner at the cabinet's symmetry axis (inner edge)
  Eigen::Vector3d along;   // unit, horizontal, from the inner edge outwards
  Eigen::Vector3d up;      // unit +z
  double width = 1000.0;
  double height = 2100.0;
  double bump_mm = 0.0;
  double reflectivity = 0.9;

  // Coordinates (a along, b up) of a point in the mirror plane, in mm from `origin`.
  Eigen::Vector2d Local(const Eigen::Vector3d& point) const;
  bool Contains(const Eigen::Vector3d& point_in_plane) const;
  // Surface displacement along the normal and the unit surface normal at a local point.
  double Displacement(const Eigen::Vector2d& local) const;
  Eigen::Vector3d SurfaceNormal(const Eigen::Vector2d& local) const;
  // Reflects a ray that meets the mirror; nullopt if it misses the mirror's rectangle.
  std::optional<Ray3d> Reflect(const Ray3d& ray) const;
  // Where an eye at `eye` sees `point` in this mirror: the virtual point behind it, on the
  // line from the eye through the mirror point where the law of reflection holds. A flat
  // mirror's is plane.ReflectPoint(point); a bumped one's differs by the local tilt.
  Eigen::Vector3d ImageOf(const Eigen::Vector3d& point, const Eigen::Vector3d& eye) const;
  std::array<Eigen::Vector3d, 4> Corners() const;
  TriangleMesh Mesh() const;
};

// Diffuse panel behind each mirror, parallel to it at a known offset, wider than the
// mirror so the laser lines on its visible margin give the slide height (the paper's
// laser calibration target).
struct Panel {
  std::string name;
  Plane plane;
  Eigen::Vector3d origin, along, up;
  double width = 0.0, height = 0.0;
  double offset_mm = 0.0;  // behind the mirror surface
  double albedo = 0.8;
  TriangleMesh Mesh() const;
};

// n parallel laser planes on a slide moving along +z at constant speed:
// laser k at time t is the plane normal · x = start + speed·t + k·spacing.
struct Lasers {
  int count = 3;
  double spacing_mm = 200.0;
  double start_mm = -50.0;
  double speed_mm_s = 150.0;
  double sheet_sigma_mm = 1.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // tilted slightly when tilt is set
  // Where the slide carries each line laser of a level (x, y): all of a level's emitters
  // send the same sheet (coplanar, from different sides), so they light more of the
  // subject without adding planes to tell apart.
  // By default one in front, one to each side and one behind the subject, in the mirrors'
  // corner (docs/cabinet-design.md).
  std::vector<Eigen::Vector2d> emitters_xy{
      {0.0, -900.0}, {-600.0, -600.0}, {600.0, -600.0}, {0.0, 800.0}};
  double power = 2.0;  // relative; the sensor maps it to DN
  // Each emitter's fan in its sheet, centred on the line from it to the subject's axis
  // (x, y = 0): a real line laser lights a sector, so the one behind the subject reaches
  // neither the mirrors nor the panels. 360 lights the whole sheet.
  double fan_deg = 90.0;

  double HeightAt(int laser, double t) const {
    return start_mm + speed_mm_s * t + laser * spacing_mm;
  }
  Plane PlaneAt(int laser, double t) const { return Plane{normal, -HeightAt(laser, t)}; }
  // Whether light from emitter `e` towards `target` (any height) leaves inside its fan.
  bool InFan(size_t e, const Eigen::Vector3d& target) const {
    if (fan_deg >= 360.0) return true;
    const Eigen::Vector2d& xy = emitters_xy[e];
    const Eigen::Vector2d to_target = target.head<2>() - xy;
    const Eigen::Vector2d to_axis = -xy;
    const double norms = to_target.norm() * to_axis.norm();
    if (norms == 0.0) return true;  // an emitter on the axis has no aim: all of it
    return to_target.dot(to_axis) >= std::cos(fan_deg * M_PI / 360.0) * norms;
  }
  // Emitter `e` on the slide, in the sheet through `point`.
  Eigen::Vector3d EmitterFor(const Eigen::Vector3d& point, size_t e = 0) const {
    const Eigen::Vector2d& xy = emitters_xy[e];
    return {xy.x(), xy.y(),
            (normal.dot(point) - normal.x() * xy.x() - normal.y() * xy.y()) / normal.z()};
  }
};

struct Sensor {
  double ambient_dn = 40.0;  // white diffuse surface under ambient light
  double laser_dn = 400.0;   // sheet centre on a white surface 1 m from the emitter, head-on
  double read_noise_dn = 2.0;
  double electrons_per_dn = 40.0;  // shot noise: variance = signal / electrons_per_dn
  double speckle_contrast = 0.2;   // multiplicative, varies along the stripe
  double blur_px = 0.7;            // Gaussian camera blur (in focus)
  // Defocus: a surface at (unfolded) distance d mm is blurred by a further Gaussian of
  // sigma defocus_px_per_diopter * |1000/d - 1000/focus_mm| px, added in quadrature to
  // blur_px (a thin lens: the blur circle grows with the dioptres off the focal plane).
  // 0 = every distance in focus.
  double focus_mm = 0.0;
  double defocus_px_per_diopter = 0.0;
  bool noise = true;

  bool Defocused() const { return focus_mm > 0 && defocus_px_per_diopter > 0; }
  // The camera's blur sigma (px) at that distance.
  double BlurAt(double distance_mm) const;
};

// How laser light spreads in a surface before it leaves it. Skin scatters a red laser
// under its surface: the stripe comes out broadened (a Gaussian of sigma_mm added to the
// sheet's, in quadrature) and softened on one side (an exponential tail of tail_mm, along
// +laser normal if positive, -normal if negative). The sheet's power is kept. The truth is
// still the laser plane's trace on the surface; an asymmetric profile's light centre is
// off it (its mean by tail_mm along the normal), which is a bias of the surface, not of the
// estimator. Panels, floor and target spread nothing.
struct LightSpread {
  double sigma_mm = 0.0;
  double tail_mm = 0.0;
  bool Active() const { return sigma_mm > 0 || tail_mm != 0; }
};

struct Scene {
  std::vector<SceneCamera> cameras;
  std::array<Mirror, 2> mirrors;  // [0] left (x < 0), [1] right
  std::array<Panel, 2> panels;
  double floor_albedo = 0.25;
  double subject_albedo = 0.6;
  LightSpread subject_light_spread;  // none: a matt, opaque surface
  Lasers lasers;
  Sensor sensor;
  Subject subject;
  std::optional<RenderedTarget> target;
  std::optional<Chessboard> chessboard;  // held for a lens calibration
  int frames = 350;
  uint64_t seed = 1;

  // Scene file with every key optional (defaults documented in docs/virtual-cabinet.md);
  // errors are ConfigError naming file and key.
  static Scene Load(const std::filesystem::path& file);
  static Scene Parse(const nlohmann::json& json, const std::string& file_name,
                     const std::filesystem::path& base_dir);

  double FrameTime(int frame) const { return frame / cameras.at(0).fps; }
  // The cabinet's true calibration in the calibration.json schema.
  nlohmann::json TrueCalibration() const;
};

}  // namespace mirrorscan::virtual_cabinet

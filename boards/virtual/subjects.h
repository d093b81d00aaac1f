#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/body_model.h"
#include "boards/virtual/mesh.h"
#include "common/config/json_reader.h"

namespace mirrorscan::virtual_cabinet {

// What stands in the virtual cabinet: one or more closed triangle meshes ("parts",
// which may overlap each other) in world coordinates, plus ground truth about them.
//
// metadata always holds "type", "params" (every parameter, defaults filled in) and
// "parts": [{"name", "first_triangle", "triangle_count"}], the contiguous triangle ranges
// of the separately closed parts, so a renderer can tell e.g. the cuboid from its tripod.
struct Subject {
  std::string type;  // "cuboid", "cylinder", "mannequin", "body", "mesh" or "none"
  TriangleMesh mesh;
  nlohmann::json metadata;
  // Per triangle (a body's skin, hair and underwear); empty: the scene's subject albedo.
  std::vector<float> triangle_albedo;
};

// The paper's test body (227.7 x 206.6 x 316.8 mm) on a tripod: three splayed legs
// (12 mm radius tubes) from a head under the cuboid to the floor, and a short centre
// column from the head up into the cuboid's underside.
// Metadata adds "size_mm", "center_mm", "yaw_deg" and "corners_mm": 8 points, corner i
// at local (+-x, +-y, +-z)/2 with the sign + where bit 0 (x), 1 (y), 2 (z) of i is set.
struct CuboidParams {
  Eigen::Vector3d size_mm{227.7, 206.6, 316.8};  // x (width), y (depth), z (height)
  Eigen::Vector3d center_mm{0.0, 0.0, 1300.0};
  double yaw_deg = 0.0;  // about +z, counter-clockwise seen from above
};

// An upright closed cylinder (flat caps), 720 segments around.
struct CylinderParams {
  double radius_mm = 150.0;
  double height_mm = 1000.0;
  double bottom_mm = 400.0;  // z of the bottom cap
  Eigen::Vector2d center_mm{0.0, 0.0};
};

// A parametric human-like body facing -y (the camera). Its torso cross-sections are
// ellipses; at the chest, waist and hip stations the ellipse's exact perimeter is the
// requested girth. By default it stands in an A-pose with the arms held clear of the
// torso at and below chest height, so a horizontal girth at any station cuts only the
// torso there; `arm_angle_deg` poses the arms instead: hanging nearer the torso (down to
// touching it) or further out, or raised above the shoulders, clear of the mirrors.
// Metadata adds "height_mm", "arm_angle_deg", for "chest", "waist" and "hip"
// {"girth_mm", "z_mm", "semi_axes_mm": [half width, half depth]}, and "truth": every
// measurement host/measurement takes, by its definitions (docs/measurement.md), worked
// out from the defining shapes (MannequinMeasurementTruth).
struct MannequinParams {
  double height_mm = 1750.0;  // top of the head
  double chest_girth_mm = 960.0;
  double waist_girth_mm = 800.0;
  double hip_girth_mm = 1000.0;
  Eigen::Vector2d center_mm{0.0, 0.0};
  double yaw_deg = 0.0;  // about +z, counter-clockwise seen from above
  // Arm angle from hanging straight down, in the body's frontal plane: 4..60 hangs the
  // arms, 100..150 raises them. Unset: the smallest A-pose angle keeping the arms 50 mm
  // clear of the torso at the chest, waist and hip.
  std::optional<double> arm_angle_deg;
};

// A mesh file; its vertices map to world as translation + R * (scale * p) with
// R = Rz * Ry * Rx (angles in degrees about the world axes).
// Metadata adds "vertex_count" and "triangle_count".
struct MeshParams {
  std::filesystem::path path;  // PLY, OBJ or STL
  double scale = 1.0;
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();  // rx, ry, rz
};

// Parses the scene file's "subject" object:
//   {"type": "cuboid", "size_mm": [x, y, z], "center_mm": [x, y, z], "yaw_deg": a}
//   {"type": "cylinder", "radius_mm": r, "height_mm": h, "bottom_mm": z, "center_mm": [x, y]}
//   {"type": "mannequin", "height_mm": h, "chest_girth_mm": c, "waist_girth_mm": w,
//    "hip_girth_mm": p, "center_mm": [x, y], "yaw_deg": a, "arm_angle_deg": g}
//   {"type": "body", ...BodyParams' keys (body_model.h)..., "cell_mm": c}
//   {"type": "mesh", "path": p, "scale": s, "translation_mm": [x, y, z],
//    "rotation_deg": [rx, ry, rz]}
//   {"type": "none"}
// Missing keys take the defaults above; unknown keys and bad values are ConfigErrors
// naming the key. A relative mesh path is resolved against `base_dir` (the scene
// file's directory).
Subject ParseSubject(const JsonReader& subject, const std::filesystem::path& base_dir = {});

// The builders throw std::invalid_argument on parameters ParseSubject would reject.
Subject MakeCuboidOnTripod(const CuboidParams& params);
Subject MakeCylinder(const CylinderParams& params);
Subject MakeMannequin(const MannequinParams& params);
// A missing, unreadable or empty file is a ConfigError naming the file.
Subject LoadMeshSubject(const MeshParams& params);
Subject MakeNoSubject();

// A mannequin's measurements by host/measurement's definitions (docs/measurement.md),
// from its defining shapes (ellipse sections, cones, cylinder, ellipsoid), not from its
// mesh: {"stature_mm", "crotch_height_mm", "chest_girth_mm", "waist_girth_mm",
// "hip_girth_mm", "thigh_girth_mm", "thigh_z_mm", "neck_girth_mm", "upper_arm_girth_mm",
// "shoulder_breadth_mm", "arm_length_mm", "shoulder_points_mm", "wrist_points_mm"}
// (points in world, left arm first). The arm values are null for raised arms, which have
// no shoulder point by those definitions.
nlohmann::json MannequinMeasurementTruth(const MannequinParams& params);

// The exact tape girth of the mannequin's horizontal section at height z: the torso's
// ellipse between the crotch and the arms' junction with the torso, each leg's circle
// below the crotch. Nothing (nullopt) elsewhere, where the section mixes parts.
struct GirthTruth {
  std::string part;  // "torso", "left_leg" or "right_leg" (each leg has the same girth)
  double girth_mm;
};
std::optional<GirthTruth> MannequinGirthTruth(const MannequinParams& params, double z_mm);

// Exact perimeter of an ellipse with semi-axes a and b (arithmetic-geometric mean,
// relative error ~1e-15).
double EllipsePerimeter(double a, double b);

}  // namespace mirrorscan::virtual_cabinet

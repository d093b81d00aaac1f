#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "boards/virtual/mesh.h"

namespace mirrorscan::virtual_cabinet {

// A human body for the virtual cabinet (docs/virtual-cabinet.md, "Human bodies"): one
// smooth closed surface, the zero set of a field of blended implicit primitives (ellipse
// lofts for the torso, tapered capsules for the limbs and neck, ellipsoids for the head,
// face, bust, buttocks, belly, shoulder blades, hands and feet) hung on a skeleton.
// The skeleton's joints come from the stature and the published proportions; the pose
// moves the joints; the shape parameters size the primitives, and the builder solves the
// sizes so that the stated girths are the surface's (tape) girths.
//
// Body frame: millimetres, z up from the floor, the body facing -y (the camera), +x the
// body's left.
struct BodyParams {
  std::string sex = "male";  // "male" or "female"
  double stature_mm = 1750.0;
  double chest_girth_mm = 980.0;    // bust girth for a woman: over the bust points
  double underbust_girth_mm = 0.0;  // 0: from the chest (men: 0.93x, women: 0.84x)
  double waist_girth_mm = 850.0;
  double hip_girth_mm = 990.0;
  double thigh_girth_mm = 560.0;
  double upper_arm_girth_mm = 310.0;
  double neck_girth_mm = 0.0;        // 0: from the chest and sex
  double shoulder_breadth_mm = 0.0;  // biacromial; 0: 0.230 (men) or 0.222 (women) x stature
  double leg_length_mm = 0.0;        // crotch height; 0: 0.472 x stature
  double belly = 0.3;                // prominence 0..1: the abdomen's bulge in front of the waist
  double bust = 0.5;                 // prominence 0..1 (women's breasts; men's pectorals are small)

  // Pose (the standard scanning posture by default).
  double arm_abduction_deg = 25.0;  // each arm from hanging straight down, frontal plane
  double elbow_bend_deg = 0.0;      // forearm forward from the upper arm's line
  double feet_apart_mm = 0.0;       // ankle centres' distance; 0: hip width (legs clear)
  double yaw_deg = 0.0;             // the whole body about +z, counter-clockwise from above
  double lean_deg = 0.0;       // back (+, away from the camera) or forward (-) about the ankles
  double head_turn_deg = 0.0;  // to the body's left (+) about the neck
  std::string hands = "fist";  // "fist" or "open"
  Eigen::Vector2d center_mm{0.0, 0.0};

  // Materials: albedo at the lasers' red wavelength (docs/virtual-cabinet.md).
  double skin_albedo = 0.55;
  double hair_albedo = 0.05;
  double underwear_albedo = 0.06;

  // Throws std::invalid_argument naming the parameter.
  void Validate() const;
  nlohmann::json ToJson() const;
};

// Named points of the body in world coordinates: skeleton joints (centres inside the
// body) and surface landmarks (on the surface; docs/virtual-cabinet.md says how each is
// placed). Left = the body's left (+x before yaw).
struct BodyLandmarks {
  Eigen::Vector3d vertex;                    // top of the head, on the surface
  Eigen::Vector3d cervicale;                 // on the back surface at C7
  std::array<Eigen::Vector3d, 2> acromion;   // [left, right], on the surface
  std::array<Eigen::Vector3d, 2> side_neck;  // where neck meets shoulder, on the surface
  std::array<Eigen::Vector3d, 2> elbow;      // olecranon (back of the elbow), surface
  std::array<Eigen::Vector3d, 2> wrist;      // ulnar styloid (joint centre line), surface
  std::array<Eigen::Vector3d, 2> shoulder_joint, elbow_joint, wrist_joint;
  std::array<Eigen::Vector3d, 2> hip_joint, knee_joint, ankle_joint;
  Eigen::Vector3d crotch;  // on the surface between the legs
  // Heights (body frame, before lean) of the girth stations, and the body's axes.
  double chest_z = 0, underbust_z = 0, waist_z = 0, hip_z = 0, thigh_z = 0, knee_z = 0, neck_z = 0,
         back_width_z = 0;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();        // the trunk's axis (lean)
  Eigen::Vector3d forward = -Eigen::Vector3d::UnitY();  // the body's front (yaw)
  Eigen::Vector3d left = Eigen::Vector3d::UnitX();
  Eigen::Vector3d ankle_center;  // the lean's pivot, world
  // The upright body frame (the stations' heights) to world: yaw, lean, position.
  Eigen::Affine3d world_from_upright = Eigen::Affine3d::Identity();
  nlohmann::json ToJson() const;
  static BodyLandmarks FromJson(const nlohmann::json& json);  // what ToJson wrote
};

// The skeleton's parts, as the sim subject's metadata names them ("parts": triangle ranges
// in this order). The trunk carries the neck and head.
enum class BodyPart { kTrunk, kLeftArm, kRightArm, kLeftLeg, kRightLeg };
const char* BodyPartName(BodyPart part);

// The body's field: negative inside, positive outside, about a distance in mm near the
// surface. Built once; Evaluate is thread-safe.
class BodyField {
 public:
  explicit BodyField(const BodyParams& params);  // solves the primitive sizes
  ~BodyField();
  BodyField(BodyField&&) noexcept;

  double Evaluate(const Eigen::Vector3d& point_in_world) const;
  // Which part's primitives are nearest the surface at a world point.
  BodyPart PartAt(const Eigen::Vector3d& point_in_world) const;
  // Which region the surface near a world point belongs to: "skin", "hair", "underwear".
  const char* RegionAt(const Eigen::Vector3d& point_in_world) const;
  Eigen::AlignedBox3d Bounds() const;  // contains the whole surface, world
  const BodyLandmarks& landmarks() const;
  const BodyParams& params() const;
  // The builder's own figures (stature, girths) of the field, for the metadata.
  nlohmann::json SolvedFigures() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A body as a subject: the field meshed (closed, edge-manifold), per-triangle albedo
// from the regions, landmarks and the truth measurements (body_truth.h) in the metadata.
// `cell_mm` is the mesher's grid step. Throws std::invalid_argument on bad parameters.
struct Subject;
Subject MakeBody(const BodyParams& params, double cell_mm = 4.0);

}  // namespace mirrorscan::virtual_cabinet

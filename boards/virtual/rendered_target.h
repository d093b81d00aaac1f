// The factory calibration target as the virtual cabinet renders it. Its geometry (panels,
// marker ids and corners) is the physical object's, common/target/target.h; this adds
// what only a renderer needs: the ArUco markers' module patterns as albedo on the panels'
// front faces, and the panels as solid boxes for the ray tracer.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "boards/virtual/mesh.h"
#include "common/target/target.h"

namespace mirrorscan::virtual_cabinet {

inline constexpr double kTargetBlackAlbedo = 0.05;
inline constexpr double kTargetWhiteAlbedo = 0.85;
// Panel backs, edges and anything else of the target that is not a front face.
inline constexpr double kTargetBodyAlbedo = kTargetWhiteAlbedo;
inline constexpr double kTargetPanelThicknessMm = 10.0;
// A point counts as on a front face when within this distance of its plane; far above
// ray-tracing round-off, far below the panel thickness.
inline constexpr double kTargetSurfaceToleranceMm = 0.5;

// Is-a CalibrationTarget (the same panels and markers), with its look.
class RenderedTarget : public CalibrationTarget {
 public:
  explicit RenderedTarget(const TargetConfig& config);

  // The three panels as closed boxes kTargetPanelThicknessMm thick, mitred where they
  // meet, front faces exactly on the panel planes; triangles CCW seen from outside.
  TriangleMesh Mesh() const;

  // Reflectance at a world point on a panel's front face (kTargetBlackAlbedo or
  // kTargetWhiteAlbedo); nullopt when the point is not on a front face (anywhere else on
  // the target is kTargetBodyAlbedo).
  std::optional<double> Albedo(const Eigen::Vector3d& point_in_world) const;

  // Mean reflectance over a square footprint of side `footprint_mm` centred on the point,
  // lying in the panel plane with sides along the panel's right/up, computed from the exact
  // area covered by black modules, so renders are alias-free. The part of the footprint
  // beyond the panel's edge is left out of the mean. nullopt as for Albedo.
  std::optional<double> AlbedoArea(const Eigen::Vector3d& point_in_world,
                                   double footprint_mm) const;

 private:
  // Panel whose front face holds the point, and the point's (u right, v up) coordinates in
  // it; nullopt when none does.
  struct PanelHit {
    int panel;
    Eigen::Vector2d uv;
  };
  std::optional<PanelHit> FindPanel(const Eigen::Vector3d& point_in_world) const;
  // Area of black inside the axis-aligned rectangle [u0,u1]x[v0,v1] of a panel.
  double BlackArea(int panel, double u0, double u1, double v0, double v1) const;

  // A marker's modules in its panel's (u, v) coordinates.
  struct MarkerLayout {
    double left = 0.0, top = 0.0;  // u of its left edge, v of its top edge
    double module = 0.0;           // side of one of its 6 x 6 modules (border included)
    // [row from top][column from left]
    std::array<std::array<bool, kTargetMarkerModules>, kTargetMarkerModules> black{};
  };
  std::vector<MarkerLayout> layouts_;  // parallel to markers()
};

}  // namespace mirrorscan::virtual_cabinet

#pragma once
// Shared by the target's tests and the rendered target's: the configurations they check
// and a panel's own coordinates, computed here rather than trusted from the class.

#include <vector>

#include <Eigen/Core>

#include "common/target/target.h"

namespace mirrorscan::target_test {

inline TargetConfig RotatedConfig() {
  TargetConfig c;
  c.center_mm = {35.0, -20.0};
  c.yaw_deg = 17.0;
  c.bottom_mm = 150.0;
  c.panel_width_mm = 450.0;
  c.panel_height_mm = 1500.0;
  c.marker_size_mm = 132.0;
  return c;
}

inline std::vector<TargetConfig> Configs() { return {TargetConfig{}, RotatedConfig()}; }

inline Eigen::Vector2d PanelUv(const TargetPanel& p, const Eigen::Vector3d& x) {
  return {p.right.dot(x - p.origin), p.up.dot(x - p.origin)};
}

}  // namespace mirrorscan::target_test

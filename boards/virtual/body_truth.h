#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "boards/virtual/body_model.h"
#include "boards/virtual/mesh.h"

namespace mirrorscan::virtual_cabinet {

// A body's measurements after ISO 8559-1, taken on its exact surface (the mesh) with the
// skeleton's landmarks: section code of its own (plane cuts chained into loops, a tape as
// the loop's convex hull), independent of host/measurement. Every value is
// {"value_mm", "definition"} (docs/virtual-cabinet.md lists the definitions and how each
// landmark is placed); a value that cannot be taken (a loop merged with another part) is
// {"value_mm": null, "definition", "why"}.
nlohmann::json BodyMeasurementTruth(const TriangleMesh& mesh, const BodyLandmarks& landmarks);

// The closed loops where a plane cuts a closed mesh, each as its points in order.
std::vector<std::vector<Eigen::Vector3d>> CutLoops(const TriangleMesh& mesh,
                                                   const Eigen::Vector3d& plane_point,
                                                   const Eigen::Vector3d& plane_normal);

// The perimeter of the convex hull of a loop lying in the plane with that normal (a tape
// around it bridges the hollows).
double TapeLength(const std::vector<Eigen::Vector3d>& loop, const Eigen::Vector3d& normal);

}  // namespace mirrorscan::virtual_cabinet

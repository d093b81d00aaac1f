#pragma once

#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "boards/virtual/mesh.h"
#include "common/geometry/plane.h"

namespace mirrorscan::virtual_cabinet {

struct RayHit {
  double t = 0.0;
  int geometry = -1;
  int triangle = -1;
  Eigen::Vector3d point;   // recomputed in double precision on the hit triangle
  Eigen::Vector3d normal;  // the triangle's outward unit normal
};

// Thin wrapper over Embree 3 (Debian's libembree). Embree finds the triangle in float;
// the hit point is then recomputed in double on that triangle's plane, so rendered
// geometry agrees with the double-precision ground truth.
class RayTracer {
 public:
  RayTracer();
  ~RayTracer();
  RayTracer(const RayTracer&) = delete;
  RayTracer& operator=(const RayTracer&) = delete;

  // Returns the geometry id. Call Commit() after the last mesh.
  int AddMesh(const TriangleMesh& mesh);
  void Commit();

  std::optional<RayHit> Intersect(const Ray3d& ray, double t_min, double t_max) const;
  bool Occluded(const Ray3d& ray, double t_min, double t_max) const;
  const TriangleMesh& mesh(int geometry) const { return meshes_.at(geometry); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<TriangleMesh> meshes_;
};

}  // namespace mirrorscan::virtual_cabinet

#include "host/meshing/test_clouds.h"

#include <random>
#include <string>

#include <open3d/t/geometry/RaycastingScene.h>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"

namespace mirrorscan::meshing::testing_clouds {

namespace {
virtual_cabinet::Scene MannequinScene() {
  return virtual_cabinet::Scene::Load(std::string(MIRRORSCAN_SOURCE_DIR) +
                                      "/boards/virtual/scenes/mannequin.json");
}
}  // namespace

Mesh MannequinSurface() {
  const virtual_cabinet::Scene scene = MannequinScene();
  Mesh mesh;
  mesh.vertices = scene.subject.mesh.vertices;
  mesh.triangles = scene.subject.mesh.triangles;
  return mesh;
}

TruthCloud MannequinTruthCloud(double noise_mm, int frame_step) {
  using virtual_cabinet::Material;
  const virtual_cabinet::Scene scene = MannequinScene();
  const virtual_cabinet::Renderer renderer(scene);
  TruthCloud truth;
  for (int frame = 0; frame < scene.frames; frame += frame_step) {
    for (int camera = 0; camera < static_cast<int>(scene.cameras.size()); ++camera) {
      for (const auto& peak : renderer.Truth(camera, scene.FrameTime(frame))) {
        if (peak.material != Material::kSubject || static_cast<int>(peak.view) > 2) continue;
        truth.exact_points.push_back(peak.point_in_world);
        truth.camera.push_back(static_cast<uint8_t>(camera));
        truth.view.push_back(static_cast<uint8_t>(peak.view));
      }
    }
  }
  const auto& subject = scene.subject.mesh;
  truth.surface.vertices = subject.vertices;
  truth.surface.triangles = subject.triangles;

  namespace o3c = open3d::core;
  std::vector<float> vertices, queries;
  std::vector<uint32_t> triangles;
  for (const auto& v : subject.vertices) {
    vertices.insert(vertices.end(), {float(v.x()), float(v.y()), float(v.z())});
  }
  for (const auto& t : subject.triangles) {
    triangles.insert(triangles.end(), {uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
  }
  for (const auto& p : truth.exact_points) {
    queries.insert(queries.end(), {float(p.x()), float(p.y()), float(p.z())});
  }
  open3d::t::geometry::RaycastingScene raycasting;
  raycasting.AddTriangles(o3c::Tensor(vertices, {long(subject.vertices.size()), 3}, o3c::Float32),
                          o3c::Tensor(triangles, {long(subject.triangles.size()), 3}, o3c::UInt32));
  const auto closest = raycasting.ComputeClosestPoints(
      o3c::Tensor(queries, {long(truth.exact_points.size()), 3}, o3c::Float32));
  const o3c::Tensor ids = closest.at("primitive_ids").To(o3c::Int64);
  const int64_t* id = ids.GetDataPtr<int64_t>();
  std::mt19937 random(11);
  std::normal_distribution<double> noise(0.0, noise_mm);
  for (size_t i = 0; i < truth.exact_points.size(); ++i) {
    const Eigen::Vector3d normal = subject.TriangleNormal(static_cast<int>(id[i]));
    truth.cloud.points.push_back(truth.exact_points[i] +
                                 (noise_mm > 0 ? noise(random) : 0.0) * normal);
    truth.cloud.normals.push_back(normal);
  }
  return truth;
}

}  // namespace mirrorscan::meshing::testing_clouds

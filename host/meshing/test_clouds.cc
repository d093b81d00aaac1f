#include "host/meshing/test_clouds.h"

#include <memory>
#include <random>
#include <string>

#include <open3d/t/geometry/RaycastingScene.h>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"

namespace mirrorscan::meshing::testing_clouds {

namespace {

namespace o3c = open3d::core;

virtual_cabinet::Scene MannequinScene() {
  return virtual_cabinet::Scene::Load(std::string(MIRRORSCAN_SOURCE_DIR) +
                                      "/boards/virtual/scenes/mannequin.json");
}

// The surface for Open3D's distance and closest-point queries (in float).
std::unique_ptr<open3d::t::geometry::RaycastingScene> QueryScene(const TriangleMesh& surface) {
  std::vector<float> vertices;
  std::vector<uint32_t> triangles;
  for (const auto& v : surface.vertices)
    vertices.insert(vertices.end(), {float(v.x()), float(v.y()), float(v.z())});
  for (const auto& t : surface.triangles) {
    // Open3D's closest-point query asserts on a triangle of no area (Poisson leaves a few).
    const Eigen::Vector3f a = surface.vertices[t[0]].cast<float>();
    const Eigen::Vector3f b = surface.vertices[t[1]].cast<float>();
    const Eigen::Vector3f c = surface.vertices[t[2]].cast<float>();
    if ((b - a).cross(c - a).squaredNorm() <= 0.0f) continue;
    triangles.insert(triangles.end(), {uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
  }
  auto scene = std::make_unique<open3d::t::geometry::RaycastingScene>();
  scene->AddTriangles(o3c::Tensor(vertices, {long(surface.vertices.size()), 3}, o3c::Float32),
                      o3c::Tensor(triangles, {long(triangles.size() / 3), 3}, o3c::UInt32));
  return scene;
}

o3c::Tensor Queries(const std::vector<Eigen::Vector3d>& points) {
  std::vector<float> queries;
  for (const auto& p : points)
    queries.insert(queries.end(), {float(p.x()), float(p.y()), float(p.z())});
  return o3c::Tensor(queries, {long(points.size()), 3}, o3c::Float32);
}

}  // namespace

TriangleMesh MannequinSurface() { return MannequinScene().subject.mesh; }

TruthCloud MannequinTruthCloud(double noise_mm, int frame_step) {
  using virtual_cabinet::Material;
  const virtual_cabinet::Scene scene = MannequinScene();
  const virtual_cabinet::Renderer renderer(scene);
  TruthCloud truth;
  std::vector<std::pair<uint8_t, uint8_t>> camera_view;
  for (int frame = 0; frame < scene.frames; frame += frame_step) {
    for (int camera = 0; camera < static_cast<int>(scene.cameras.size()); ++camera) {
      for (const auto& peak : renderer.Truth(camera, scene.FrameTime(frame))) {
        if (peak.material != Material::kSubject || static_cast<int>(peak.view) > 2) continue;
        truth.exact_points.push_back(peak.point_in_world);
        camera_view.emplace_back(static_cast<uint8_t>(camera), static_cast<uint8_t>(peak.view));
      }
    }
  }
  const auto& subject = scene.subject.mesh;
  truth.surface = subject;

  const auto closest = QueryScene(subject)->ComputeClosestPoints(Queries(truth.exact_points));
  const o3c::Tensor ids = closest.at("primitive_ids").To(o3c::Int64);
  const int64_t* id = ids.GetDataPtr<int64_t>();
  std::mt19937 random(11);
  std::normal_distribution<double> noise(0.0, noise_mm);
  for (size_t i = 0; i < truth.exact_points.size(); ++i) {
    const Eigen::Vector3d normal = subject.TriangleNormal(static_cast<int>(id[i]));
    CloudPoint& point = truth.cloud.points.emplace_back();
    point.point_in_world =
        (truth.exact_points[i] + (noise_mm > 0 ? noise(random) : 0.0) * normal).cast<float>();
    point.normal = normal.cast<float>();
    point.camera = camera_view[i].first;
    point.view = static_cast<PointView>(camera_view[i].second);
  }
  return truth;
}

std::vector<float> DistancesTo(const TriangleMesh& surface,
                               const std::vector<Eigen::Vector3d>& points) {
  const o3c::Tensor distance = QueryScene(surface)->ComputeDistance(Queries(points));
  const float* d = distance.GetDataPtr<float>();
  return std::vector<float>(d, d + points.size());
}

}  // namespace mirrorscan::meshing::testing_clouds

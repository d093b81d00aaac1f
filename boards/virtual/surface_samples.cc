#include "boards/virtual/surface_samples.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace mirrorscan::virtual_cabinet {
namespace {

// Whether `camera` sees `point` in `view` (centre, left or right): the pixel it projects
// to traces back to the same subject point.
bool Sees(const Renderer& renderer, int camera, View view, const Eigen::Vector3d& point) {
  const Scene& scene = renderer.scene();
  const Camera& model = scene.cameras[camera].camera;
  const std::optional<Eigen::Vector2d> pixel =
      view == View::kCenter
          ? model.ProjectWorld(point)
          : model.ProjectViaMirror(point, scene.mirrors[view == View::kLeft ? 0 : 1].plane);
  if (!pixel) return false;
  const auto& intrinsics = model.intrinsics;
  if (pixel->x() < -0.5 || pixel->y() < -0.5 || pixel->x() > intrinsics.width - 0.5 ||
      pixel->y() > intrinsics.height - 0.5) {
    return false;
  }
  const SurfaceSample seen = renderer.TracePixel(camera, *pixel);
  return seen.view == view && seen.material == Material::kSubject &&
         (seen.hit.point - point).norm() < 0.5;
}

}  // namespace

std::vector<TruthSurfaceSample> SampleSubjectSurface(const Renderer& renderer, double spacing_mm,
                                                     uint64_t seed) {
  const Scene& scene = renderer.scene();
  const TriangleMesh& mesh = scene.subject.mesh;
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Heights some laser crosses during the sweep.
  const double last_t = scene.FrameTime(std::max(0, scene.frames - 1));
  const double lowest = scene.lasers.HeightAt(0, 0.0);
  const double highest = scene.lasers.HeightAt(scene.lasers.count - 1, last_t);
  std::vector<TruthSurfaceSample> samples;
  const double per_mm2 = 1.0 / (spacing_mm * spacing_mm);
  for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices[tri[2]];
    const double expected = 0.5 * (b - a).cross(c - a).norm() * per_mm2;
    int count = static_cast<int>(expected);
    if (uniform(random) < expected - count) ++count;
    for (int k = 0; k < count; ++k) {
      double r1 = uniform(random), r2 = uniform(random);
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      TruthSurfaceSample sample;
      sample.point_in_world = a + r1 * (b - a) + r2 * (c - a);
      sample.normal = mesh.TriangleNormal(t);
      const Eigen::Vector3d& p = sample.point_in_world;
      const bool lit =
          p.z() >= lowest && p.z() <= highest && renderer.LaserIrradiance(p, sample.normal) > 0.0;
      if (lit) {
        for (int camera = 0; camera < static_cast<int>(scene.cameras.size()) && !sample.visible;
             ++camera) {
          for (View view : {View::kCenter, View::kLeft, View::kRight}) {
            if (Sees(renderer, camera, view, p)) {
              sample.visible = true;
              break;
            }
          }
        }
      }
      samples.push_back(sample);
    }
  }
  return samples;
}

}  // namespace mirrorscan::virtual_cabinet

#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "boards/virtual/raytracer.h"
#include "boards/virtual/scene.h"

namespace cv {
class Mat;
}  // namespace cv

namespace mirrorscan::virtual_cabinet {

// How a camera ray reached the surface it sees: directly, or through one or two mirrors.
enum class View : uint8_t {
  kCenter = 0,
  kLeft = 1,
  kRight = 2,
  kLeftRight = 3,
  kRightLeft = 4,
  kNone = 255
};
const char* ViewName(View view);
// Mirror indices (0 left, 1 right) in the order the camera ray meets them.
std::vector<int> MirrorPath(View view);

enum class Material : uint8_t { kNone, kFloor, kPanel, kMirror, kSubject, kTarget, kChessboard };
const char* MaterialName(Material material);

struct SurfaceSample {
  View view = View::kNone;
  Material material = Material::kNone;
  RayHit hit;                 // the diffuse surface finally seen, normal facing the ray
  Ray3d last_ray;             // the ray segment that meets it (after reflections)
  double path_length = 0.0;   // camera to surface, unfolded
  double transmission = 1.0;  // product of mirror reflectivities on the way
};

struct GrayImage {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;  // row-major
  uint8_t at(int u, int v) const { return pixels[static_cast<size_t>(v) * width + u]; }
};

// The mean signal in DN before noise, saturation and quantisation.
struct FloatImage {
  int width = 0, height = 0;
  std::vector<float> pixels;  // row-major
  float at(int u, int v) const { return pixels[static_cast<size_t>(v) * width + u]; }
};

// One point of the ground truth: where a laser stripe's centre crosses an image column.
struct TruthPeak {
  int camera = 0;
  int laser = 0;
  View view = View::kCenter;
  enum Material material = Material::kSubject;  // subject, target or panel
  int u = 0;                                    // image column
  double v = 0.0;                               // exact sub-pixel row of the stripe centre
  Eigen::Vector3d point_in_world;               // on the laser plane and on the surface
  // Expected stripe peak before blur and noise (after the subject's light spread).
  double peak_dn = 0.0;
};

// Renders the virtual cabinet. The scene is static, so everything that does not depend
// on the slide position (what each pixel sees, through which mirrors, whether the lasers
// can reach it, the ambient image) is computed once per camera; a frame then only
// evaluates the laser planes near their stripes, the camera blur and the sensor.
class Renderer {
 public:
  explicit Renderer(const Scene& scene);
  ~Renderer();

  const Scene& scene() const { return scene_; }
  const RayTracer& tracer() const { return tracer_; }

  // Follows the camera ray through `pixel`, reflecting in the mirrors (at most two bounces).
  SurfaceSample TracePixel(int camera, const Eigen::Vector2d& pixel) const;
  // Laser light reaching a surface point along one kind of path. The laser sheets are
  // the planes lasers.normal · x = height. Direct light, and light through a flat
  // (vertical) mirror, which reflects a sheet into itself, is at the point's own sheet
  // coordinate. Light through a bumped mirror is bent out of the sheet by the surface's
  // local tilt: it reaches the point from the sheet that holds the point's image in that
  // mirror as the emitter sees it (Mirror::ImageOf, as for the camera).
  struct LaserLight {
    double sheet_mm = 0.0;    // lasers.normal · the point, or · its image in a bumped mirror
    double irradiance = 0.0;  // > 0
    int bumped_mirror = -1;   // the bumped mirror the light came through; -1: none
  };
  // At most one entry for the point's own sheet (direct and flat mirrors, summed) and one
  // per bumped mirror; none when no emitter path reaches the point.
  std::vector<LaserLight> LaserLights(const Eigen::Vector3d& point,
                                      const Eigen::Vector3d& normal) const;
  // Laser irradiance factor at a surface point (0 when no emitter path reaches it):
  // the sum over the direct path and the paths through each mirror.
  double LaserIrradiance(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) const;

  // An 8-bit frame at slide time t (seconds). frame_index seeds the sensor noise.
  GrayImage RenderFrame(int camera, double t, uint64_t frame_index, bool lasers_on = true) const;
  // The noise-free mean image of that frame (no speckle, noise, clipping or rounding), to
  // check the image model against the truth without the sensor in the way.
  FloatImage RenderRadiance(int camera, double t, bool lasers_on = true) const;
  // Stripe centres for every column each stripe crosses, in this camera at time t.
  std::vector<TruthPeak> Truth(int camera, double t) const;

 private:
  struct CameraCache;
  const CameraCache& Cache(int camera) const;
  void BuildCache(int camera) const;
  // Laser light only (CV_32F, blurred); speckle from the seed, none without one.
  cv::Mat LaserImage(int camera, double t, std::optional<uint64_t> speckle_seed) const;
  double Albedo(const RayHit& hit, double footprint_mm) const;
  // Where light through bumped mirror `m` reaching `point` left the emitter: the point's
  // image in the mirror as that emitter sees it, and the emitter, whose sheet holds it.
  struct BumpedPath {
    Eigen::Vector3d image, emitter;
  };
  BumpedPath BumpedLightPath(int m, const Eigen::Vector3d& point) const;

  Scene scene_;
  RayTracer tracer_;
  std::vector<enum Material> materials_;  // by Embree geometry id
  int first_mirror_geometry_ = -1;
  mutable std::mutex cache_mutex_;
  mutable std::vector<std::unique_ptr<CameraCache>> caches_;
};

}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <thread>
#include <tuple>

#include <opencv2/imgproc.hpp>

namespace mirrorscan::virtual_cabinet {

namespace {

constexpr double kTraceEpsilon = 1e-3;   // mm; keeps secondary rays off their own surface
constexpr double kMaxGradientMm = 10.0;  // laser-plane distance spanned by one pixel, capped
constexpr int kSub = 8;  // slices per pixel along v for the laser's blur (see LaserImage)

// Deterministic per-frame random numbers (SplitMix64), so frames render in any order or
// in parallel and a seed always gives the same images.
class FrameRandom {
 public:
  explicit FrameRandom(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  float Uniform() { return static_cast<float>(Next() >> 40) * (1.0f / 16777216.0f); }
  // Marsaglia's polar method: two standard normals per accepted pair.
  float Normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    float x, y, r2;
    do {
      x = 2.0f * Uniform() - 1.0f;
      y = 2.0f * Uniform() - 1.0f;
      r2 = x * x + y * y;
    } while (r2 >= 1.0f || r2 == 0.0f);
    const float f = std::sqrt(-2.0f * std::log(r2) / r2);
    spare_ = y * f;
    has_spare_ = true;
    return x * f;
  }

 private:
  uint64_t state_;
  float spare_ = 0.0f;
  bool has_spare_ = false;
};

uint64_t MixSeed(uint64_t a, uint64_t b, uint64_t c) {
  FrameRandom r(a * 0x632BE59BD9B4E019ull ^ (b + 0x9E3779B97F4A7C15ull) * 0xD6E8FEB86659FD93ull ^
                c);
  return r.Next();
}

// Fraction of a Gaussian blur (sigma in px) centred at offset x from a pixel's centre
// that falls into that pixel.
double PixelIntegral(double x, double sigma) {
  const double k = 1.0 / (std::numbers::sqrt2 * sigma);
  return 0.5 * (std::erf((x + 0.5) * k) - std::erf((x - 0.5) * k));
}

constexpr double kBlurStepPx = 0.01;  // defocus blur sigmas are rounded to this

// Cumulative distribution of the light across a sheet seen through a scattering surface:
// a Gaussian of sigma (mm) convolved with a one-sided exponential of length tail (mm,
// towards +w if positive): the exponentially modified Gaussian. tail 0: the Gaussian.
double SpreadCdf(double x, double sigma, double tail) {
  const double gauss = 0.5 * std::erfc(-x / (std::numbers::sqrt2 * sigma));
  if (tail == 0) return gauss;
  if (tail < 0) return 1.0 - SpreadCdf(-x, sigma, -tail);
  // Phi(x/s) - exp(-x/t + s^2/(2t^2)) Phi(x/s - s/t), with Phi(y) = erfc(-y/sqrt2)/2.
  const double exponent = -x / tail + 0.5 * sigma * sigma / (tail * tail);
  return gauss -
         0.5 * std::exp(exponent) * std::erfc(-(x / sigma - sigma / tail) / std::numbers::sqrt2);
}

// Peak of the spread profile relative to the bare sheet's (sheet sigma, the spread's
// widened sigma and tail as in LaserImage): the spread keeps the power, so it lowers the peak.
double SpreadPeakRatio(double sheet_sigma, double sigma, double tail) {
  const double step = 1e-3 * sigma;
  double peak = 0.0;
  for (double x = -4.0 * sigma; x <= 4.0 * sigma + 4.0 * std::abs(tail); x += step) {
    peak = std::max(
        peak, SpreadCdf(x + 0.5 * step, sigma, tail) - SpreadCdf(x - 0.5 * step, sigma, tail));
  }
  return peak / step * sheet_sigma * std::sqrt(2.0 * std::numbers::pi);
}

View ViewFromPath(const std::vector<int>& path) {
  if (path.empty()) return View::kCenter;
  if (path.size() == 1) return path[0] == 0 ? View::kLeft : View::kRight;
  return path[0] == 0 ? View::kLeftRight : View::kRightLeft;
}

void ParallelRows(int rows, const std::function<void(int begin, int end)>& work) {
  const int threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  const int chunk = (rows + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const int begin = t * chunk, end = std::min(rows, begin + chunk);
    if (begin < end) pool.emplace_back(work, begin, end);
  }
  for (auto& th : pool) th.join();
}

}  // namespace

const char* MaterialName(Material material) {
  switch (material) {
    case Material::kFloor:
      return "floor";
    case Material::kPanel:
      return "panel";
    case Material::kMirror:
      return "mirror";
    case Material::kSubject:
      return "subject";
    case Material::kTarget:
      return "target";
    case Material::kChessboard:
      return "chessboard";
    case Material::kNone:
      break;
  }
  return "none";
}

const char* ViewName(View view) {
  switch (view) {
    case View::kCenter:
      return "center";
    case View::kLeft:
      return "left";
    case View::kRight:
      return "right";
    case View::kLeftRight:
      return "left-right";
    case View::kRightLeft:
      return "right-left";
    case View::kNone:
      break;
  }
  return "none";
}

std::vector<int> MirrorPath(View view) {
  switch (view) {
    case View::kLeft:
      return {0};
    case View::kRight:
      return {1};
    case View::kLeftRight:
      return {0, 1};
    case View::kRightLeft:
      return {1, 0};
    default:
      return {};
  }
}

struct Renderer::CameraCache {
  struct LaserPixel {
    double w;    // laser normal · surface point (mm)
    float span;  // change of w from the pixel's top edge to its bottom edge, signed, capped
    float gain;  // DN at the sheet's centre, before speckle
    uint32_t index;
    uint16_t blur;  // index into blurs: the camera's blur at this pixel's distance
    bool spread;    // the subject's light spread applies (Scene::subject_light_spread)
  };
  int width = 0, height = 0;
  std::vector<View> views;
  cv::Mat base;                 // ambient image, blurred, CV_32F
  std::vector<LaserPixel> lit;  // pixels any laser can reach, sorted by w
  std::vector<double> blurs;    // blur sigmas (px) in use; one unless defocused
  double max_span = 0.0;
};

Renderer::Renderer(const Scene& scene) : scene_(scene) {
  auto add = [&](const TriangleMesh& mesh, enum Material material) {
    tracer_.AddMesh(mesh);
    materials_.push_back(material);
  };
  // Floor: a large quad at z = 0 facing up.
  TriangleMesh floor;
  // Far larger than any view, so its rim never makes an edge in the image.
  floor.vertices = {{-1e5, -1e5, 0}, {1e5, -1e5, 0}, {1e5, 1e5, 0}, {-1e5, 1e5, 0}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  add(floor, Material::kFloor);
  for (const auto& panel : scene_.panels) add(panel.Mesh(), Material::kPanel);
  first_mirror_geometry_ = static_cast<int>(materials_.size());
  for (const auto& mirror : scene_.mirrors) add(mirror.Mesh(), Material::kMirror);
  if (!scene_.subject.mesh.empty()) add(scene_.subject.mesh, Material::kSubject);
  if (scene_.target) add(scene_.target->Mesh(), Material::kTarget);
  if (scene_.chessboard) add(scene_.chessboard->Mesh(), Material::kChessboard);
  tracer_.Commit();
  caches_.resize(scene_.cameras.size());
}

Renderer::~Renderer() = default;

SurfaceSample Renderer::TracePixel(int camera, const Eigen::Vector2d& pixel) const {
  SurfaceSample sample;
  auto ray = scene_.cameras.at(camera).camera.RayThroughPixel(pixel);
  if (!ray) return sample;
  std::vector<int> path;
  for (int bounce = 0; bounce <= 2; ++bounce) {
    const auto hit =
        tracer_.Intersect(*ray, kTraceEpsilon, std::numeric_limits<double>::infinity());
    if (!hit) return sample;
    const enum Material material = materials_[hit->geometry];
    if (material == Material::kMirror) {
      if (bounce == 2) return sample;
      const int index = hit->geometry - first_mirror_geometry_;
      const Mirror& mirror = scene_.mirrors[index];
      const auto reflected = mirror.Reflect(*ray);
      if (!reflected) return sample;  // grazed the rim in float but not in double
      sample.path_length += (reflected->origin - ray->origin).norm();
      sample.transmission *= mirror.reflectivity;
      path.push_back(index);
      ray = reflected;
      continue;
    }
    sample.view = ViewFromPath(path);
    sample.material = material;
    sample.hit = *hit;
    if (sample.hit.normal.dot(ray->direction) > 0) sample.hit.normal = -sample.hit.normal;
    sample.last_ray = *ray;
    sample.path_length += hit->t;
    return sample;
  }
  return sample;
}

Renderer::BumpedPath Renderer::BumpedLightPath(int m, const Eigen::Vector3d& point) const {
  const Lasers& lasers = scene_.lasers;
  const Mirror& mirror = scene_.mirrors[m];
  // Start from the point's own sheet; the image moves the emitter by the bend, which moves
  // the mirror point by half as much: a few rounds settle far below a micrometre. (A scene
  // with a bumped mirror has one emitter; Scene::Parse sees to it.)
  BumpedPath path;
  path.emitter = lasers.EmitterFor(point);
  for (int round = 0; round < 4; ++round) {
    path.image = mirror.ImageOf(point, path.emitter);
    path.emitter = lasers.EmitterFor(path.image);
  }
  return path;
}

std::vector<Renderer::LaserLight> Renderer::LaserLights(const Eigen::Vector3d& point,
                                                        const Eigen::Vector3d& normal) const {
  const Lasers& lasers = scene_.lasers;
  const Eigen::Vector3d& n = lasers.normal;
  double own_sheet = 0.0;  // direct and through flat mirrors, from every emitter
  std::vector<LaserLight> lights;

  auto contribution = [&](const Eigen::Vector3d& toward, double length) {
    // A line laser spreads its power along the line: irradiance falls as 1/r.
    return std::max(0.0, normal.dot(toward)) * 1000.0 / length;
  };
  for (size_t e = 0; e < lasers.emitters_xy.size(); ++e) {
    // The emitter sits on the slide in the laser plane through the point.
    const Eigen::Vector3d emitter = lasers.EmitterFor(point, e);
    const Eigen::Vector3d d = emitter - point;
    const double r = d.norm();
    const Eigen::Vector3d dir = d / r;
    if (normal.dot(dir) > 0 && lasers.InFan(e, point) &&
        !tracer_.Occluded({point, dir}, 0.05, r - 0.05)) {
      own_sheet += contribution(dir, r);
    }
    for (const Mirror& mirror : scene_.mirrors) {
      if (mirror.bump_mm != 0.0) continue;
      const Eigen::Vector3d virtual_emitter = mirror.plane.ReflectPoint(emitter);
      const Eigen::Vector3d to_image = virtual_emitter - point;
      const double length = to_image.norm();
      const Eigen::Vector3d toward = to_image / length;
      if (normal.dot(toward) <= 0) continue;
      const Ray3d to_mirror{point, toward};
      const auto t = IntersectRayPlane(to_mirror, mirror.plane, 0.05);
      if (!t || *t >= length) continue;
      const Eigen::Vector3d on_mirror = to_mirror.At(*t);
      if (!mirror.Contains(on_mirror) || !lasers.InFan(e, on_mirror)) continue;
      if (tracer_.Occluded(to_mirror, 0.05, *t - 0.05)) continue;
      const Eigen::Vector3d back = emitter - on_mirror;
      const double back_length = back.norm();
      if (tracer_.Occluded({on_mirror, back / back_length}, 0.05, back_length - 0.05)) continue;
      own_sheet += mirror.reflectivity * contribution(toward, length);
    }
  }
  for (int m = 0; m < static_cast<int>(scene_.mirrors.size()); ++m) {
    const Mirror& mirror = scene_.mirrors[m];
    if (mirror.bump_mm == 0.0) continue;
    // Through the bumped surface: the emitter sends its light towards the point's image,
    // meets the mirror where the law of reflection holds, and the light reaches the point.
    const BumpedPath path = BumpedLightPath(m, point);
    const Ray3d sight{path.emitter, (path.image - path.emitter).normalized()};
    const auto t = IntersectRayPlane(sight, mirror.plane, 1e-6);
    if (!t) continue;
    const Eigen::Vector3d in_plane = sight.At(*t);
    if (!mirror.Contains(in_plane) || !lasers.InFan(0, in_plane)) continue;
    const Eigen::Vector3d on_mirror =
        in_plane + mirror.Displacement(mirror.Local(in_plane)) * mirror.plane.normal;
    const Eigen::Vector3d d = on_mirror - point;
    const double to_mirror_length = d.norm();
    const Eigen::Vector3d dir = d / to_mirror_length;
    if (normal.dot(dir) <= 0) continue;
    // The point must lie in front of the mirror, the emitter too.
    if (mirror.plane.SignedDistance(point) <= 0.0) continue;
    if (tracer_.Occluded({point, dir}, 0.05, to_mirror_length - 0.05)) continue;
    const Eigen::Vector3d back = path.emitter - on_mirror;
    const double back_length = back.norm();
    if (tracer_.Occluded({on_mirror, back / back_length}, 0.05, back_length - 0.05)) continue;
    const double irradiance =
        mirror.reflectivity * contribution(dir, to_mirror_length + back_length);
    if (irradiance > 0.0) lights.push_back({n.dot(path.image), irradiance, m});
  }
  if (own_sheet > 0.0) lights.push_back({n.dot(point), own_sheet, -1});
  return lights;
}

double Renderer::LaserIrradiance(const Eigen::Vector3d& point,
                                 const Eigen::Vector3d& normal) const {
  double total = 0.0;
  for (const LaserLight& light : LaserLights(point, normal)) total += light.irradiance;
  return total;
}

double Renderer::Albedo(const RayHit& hit, double footprint_mm) const {
  switch (materials_[hit.geometry]) {
    case Material::kFloor:
      return scene_.floor_albedo;
    case Material::kPanel:
      return scene_.panels[0].albedo;
    case Material::kSubject:
      return scene_.subject.triangle_albedo.empty()
                 ? scene_.subject_albedo
                 : scene_.subject.triangle_albedo.at(hit.triangle);
    case Material::kTarget: {
      const auto a = scene_.target->AlbedoArea(hit.point, footprint_mm);
      return a ? *a : 0.85;
    }
    case Material::kChessboard: {
      const auto a = scene_.chessboard->AlbedoArea(hit.point, footprint_mm);
      return a ? *a : kChessboardWhiteAlbedo;
    }
    default:
      return 0.0;
  }
}

const Renderer::CameraCache& Renderer::Cache(int camera) const {
  std::lock_guard<std::mutex> lock(cache_mutex_);
  if (!caches_.at(camera)) BuildCache(camera);
  return *caches_[camera];
}

void Renderer::BuildCache(int camera) const {
  auto cache = std::make_unique<CameraCache>();
  const SceneCamera& cam = scene_.cameras[camera];
  const int width = cam.camera.intrinsics.width, height = cam.camera.intrinsics.height;
  cache->width = width;
  cache->height = height;
  cache->views.assign(static_cast<size_t>(width) * height, View::kNone);
  cv::Mat base(height, width, CV_32F, cv::Scalar(0));
  std::vector<std::vector<CameraCache::LaserPixel>> lit_rows(height);
  const Sensor& sensor = scene_.sensor;
  const Eigen::Vector3d& laser_normal = scene_.lasers.normal;
  const LightSpread& spread = scene_.subject_light_spread;

  ParallelRows(height, [&](int row_begin, int row_end) {
    for (int v = row_begin; v < row_end; ++v) {
      for (int u = 0; u < width; ++u) {
        const SurfaceSample s = TracePixel(camera, {u, v});
        const size_t index = static_cast<size_t>(v) * width + u;
        cache->views[index] = s.view;
        if (s.view == View::kNone) continue;
        // Ray differentials: where the rays through the neighbouring half-pixels meet the
        // tangent plane, following the same mirrors.
        const Plane tangent = Plane::FromPointNormal(s.hit.point, s.hit.normal);
        auto on_tangent = [&](const Eigen::Vector2d& pixel) -> std::optional<Eigen::Vector3d> {
          auto ray = cam.camera.RayThroughPixel(pixel);
          if (!ray) return std::nullopt;
          for (int m : MirrorPath(s.view)) {
            const Plane& plane = scene_.mirrors[m].plane;
            const auto t = IntersectRayPlane(*ray, plane, -1e9);
            if (!t) return std::nullopt;
            ray = Ray3d{ray->At(*t), plane.ReflectDirection(ray->direction)};
          }
          const auto t = IntersectRayPlane(*ray, tangent, -1e9);
          if (!t) return std::nullopt;
          return ray->At(*t);
        };
        const auto up = on_tangent({u, v - 0.5}), down = on_tangent({u, v + 0.5});
        const auto left = on_tangent({u - 0.5, v}), right = on_tangent({u + 0.5, v});
        double span = kMaxGradientMm, footprint = 1.0;
        if (up && down && left && right) {
          span = std::clamp(laser_normal.dot(*down - *up), -kMaxGradientMm, kMaxGradientMm);
          footprint = std::sqrt(std::max(1e-6, (*down - *up).cross(*right - *left).norm()));
        }
        const double albedo = Albedo(s.hit, footprint);
        const double facing = std::max(0.0, -s.hit.normal.dot(s.last_ray.direction));
        base.at<float>(v, u) = static_cast<float>(sensor.ambient_dn * albedo * s.transmission *
                                                  (0.35 + 0.65 * facing));
        // Without laser power (a lens calibration's captures) no pixel is lit: skip the
        // shadow rays, most of the cost of this pass.
        if (scene_.lasers.power <= 0.0) continue;
        // The blur index holds the blur bin until the bins are numbered below.
        const auto blur_bin = static_cast<uint16_t>(
            std::min(65535l, std::lround(sensor.BlurAt(s.path_length) / kBlurStepPx)));
        // One entry per sheet the light arrives on (a bumped mirror's is its own). Across
        // the pixel a bumped mirror's sheet changes as the point's own does: the bend
        // varies over hundreds of millimetres, the pixel spans a few.
        for (const LaserLight& light : LaserLights(s.hit.point, s.hit.normal)) {
          const double gain =
              sensor.laser_dn * scene_.lasers.power * albedo * s.transmission * light.irradiance;
          if (gain < 1e-3) continue;
          lit_rows[v].push_back({light.sheet_mm, static_cast<float>(span), static_cast<float>(gain),
                                 static_cast<uint32_t>(index), blur_bin,
                                 s.material == Material::kSubject && spread.Active()});
        }
      }
    }
  });
  if (sensor.blur_px > 0)
    cv::GaussianBlur(base, base, cv::Size(0, 0), sensor.blur_px, sensor.blur_px,
                     cv::BORDER_REPLICATE);
  cache->base = base;
  std::map<uint16_t, uint16_t> blur_index;  // bin -> index into cache->blurs
  for (auto& row : lit_rows) {
    for (auto& p : row) {
      cache->max_span = std::max<double>(cache->max_span, std::abs(p.span));
      if (!sensor.Defocused()) {
        p.blur = 0;
        continue;
      }
      const auto [it, added] =
          blur_index.try_emplace(p.blur, static_cast<uint16_t>(cache->blurs.size()));
      if (added) cache->blurs.push_back(p.blur * kBlurStepPx);
      p.blur = it->second;
    }
    cache->lit.insert(cache->lit.end(), row.begin(), row.end());
  }
  if (!sensor.Defocused()) cache->blurs = {sensor.blur_px};
  std::sort(cache->lit.begin(), cache->lit.end(),
            [](const auto& a, const auto& b) { return a.w < b.w; });
  caches_[camera] = std::move(cache);
}

cv::Mat Renderer::LaserImage(int camera, double t, std::optional<uint64_t> speckle_seed) const {
  const CameraCache& cache = Cache(camera);
  const Sensor& sensor = scene_.sensor;
  const Lasers& lasers = scene_.lasers;

  cv::Mat laser(cache.height, cache.width, CV_32F, cv::Scalar(0));
  int row_min = cache.height, row_max = -1;
  const double sigma = lasers.sheet_sigma_mm;
  // Light leaving the subject: the sheet widened by the spread's Gaussian and softened by
  // its tail (a tail far shorter than the Gaussian changes nothing measurable and would
  // overflow SpreadCdf's exponential, so it is dropped).
  const LightSpread& spread = scene_.subject_light_spread;
  const double spread_sigma = std::hypot(sigma, spread.sigma_mm);
  const double spread_tail = std::abs(spread.tail_mm) < 0.05 * spread_sigma ? 0.0 : spread.tail_mm;
  const double profile_reach =
      spread.Active() ? std::max(6.0 * sigma, 6.0 * spread_sigma + 10.0 * std::abs(spread_tail))
                      : 6.0 * sigma;
  const double reach = profile_reach + 0.5 * cache.max_span;
  // Speckle: a gamma-distributed factor (mean 1, contrast C) per column and laser,
  // so it varies along the stripe but not across it.
  const double contrast = speckle_seed ? sensor.speckle_contrast : 0.0;
  std::vector<float> speckle(static_cast<size_t>(cache.width) * lasers.count, 1.0f);
  if (contrast > 0) {
    std::mt19937_64 engine(*speckle_seed);
    const double shape = 1.0 / (contrast * contrast);
    std::gamma_distribution<double> gamma(shape, 1.0 / shape);
    for (auto& s : speckle) s = static_cast<float>(gamma(engine));
  }
  // The lens blurs the continuous image before the pixels integrate it. Where a pixel
  // spans more than the sheet (mirror views), the stripe is narrower than a pixel, and
  // blurring pixel means with a sampled kernel would alias: a phase-dependent profile
  // shape that no camera produces. So along v each pixel is cut into kSub slices (the
  // sheet integrated exactly over each), and each slice is spread over the rows below and
  // above by the exact pixel integral of the Gaussian blur. Along u the stripe is wide and
  // the sampled kernel is fine. Each blur in use (one unless defocused) has its tables.
  struct BlurTables {
    double sigma;
    int radius, taps;
    std::vector<float> spread;  // kSub x taps: slice i's share of row offset j
    cv::Mat along_u;            // sampled kernel, taps x 1
  };
  std::vector<BlurTables> blurs;
  for (const double blur : cache.blurs) {
    BlurTables b;
    b.sigma = blur;
    b.radius = blur > 0 ? static_cast<int>(std::ceil(4.0 * blur)) : 0;
    b.taps = 2 * b.radius + 1;
    b.spread.assign(static_cast<size_t>(kSub) * b.taps, 0.0f);
    for (int i = 0; i < kSub; ++i) {
      const double y = -0.5 + (i + 0.5) / kSub;  // slice centre, pixel units
      for (int j = -b.radius; j <= b.radius; ++j) {
        b.spread[static_cast<size_t>(i) * b.taps + j + b.radius] =
            blur > 0 ? static_cast<float>(PixelIntegral(j - y, blur)) : 1.0f;
      }
    }
    if (blur > 0) b.along_u = cv::getGaussianKernel(b.taps, blur, CV_32F);
    blurs.push_back(std::move(b));
  }
  // One blur: the rows are blurred along u afterwards, in one filter. Several: each
  // pixel's light is spread along u with its own kernel as it is added.
  const bool one_blur = blurs.size() == 1;
  double slice[kSub];
  for (int k = 0; k < lasers.count; ++k) {
    const double h = lasers.HeightAt(k, t);
    auto it = std::lower_bound(cache.lit.begin(), cache.lit.end(), h - reach,
                               [](const auto& p, double w) { return p.w < w; });
    for (; it != cache.lit.end() && it->w <= h + reach; ++it) {
      const double s = it->w - h;
      if (std::abs(s) > (it->spread ? profile_reach : 6.0 * sigma) + 0.5 * std::abs(it->span)) {
        continue;
      }
      const int u = static_cast<int>(it->index % cache.width);
      const int v = static_cast<int>(it->index / cache.width);
      const double gain = it->gain * speckle[static_cast<size_t>(k) * cache.width + u];
      // Slice i covers w from s + span (i/kSub - 1/2) to s + span ((i+1)/kSub - 1/2);
      // slice[i] is the sheet integrated over it, in pixel units (erf at shared edges).
      if (it->spread) {
        // The sheet's power (gain x sigma sqrt(2 pi) per mm) spread by the surface; a
        // pixel spanning (nearly) nothing samples the profile's density.
        const double extent = std::max<double>(std::abs(it->span), 1e-3 * sigma);
        const double span = it->span < 0 ? -extent : extent;
        const double scale = gain * sigma * std::sqrt(2.0 * std::numbers::pi) / extent;
        double lower = SpreadCdf(s - 0.5 * span, spread_sigma, spread_tail);
        for (int i = 0; i < kSub; ++i) {
          const double upper = SpreadCdf(s + span * (static_cast<double>(i + 1) / kSub - 0.5),
                                         spread_sigma, spread_tail);
          slice[i] = scale * std::abs(upper - lower);
          lower = upper;
        }
      } else if (std::abs(it->span) < 1e-3 * sigma) {
        const double point = gain / kSub * std::exp(-0.5 * s * s / (sigma * sigma));
        for (double& x : slice) x = point;
      } else {
        const double k_erf = 1.0 / (std::numbers::sqrt2 * sigma);
        const double scale = gain * sigma * std::sqrt(std::numbers::pi / 2.0) / it->span;
        double lower = std::erf((s - 0.5 * it->span) * k_erf);
        for (int i = 0; i < kSub; ++i) {
          const double upper =
              std::erf((s + it->span * (static_cast<double>(i + 1) / kSub - 0.5)) * k_erf);
          slice[i] = scale * (upper - lower);
          lower = upper;
        }
      }
      const BlurTables& b = blurs[it->blur];
      for (int j = -b.radius; j <= b.radius; ++j) {
        const int row = v + j;
        if (row < 0 || row >= cache.height) continue;
        double sum = 0.0;
        for (int i = 0; i < kSub; ++i)
          sum += slice[i] * b.spread[static_cast<size_t>(i) * b.taps + j + b.radius];
        float* out = laser.ptr<float>(row);
        if (one_blur || b.sigma <= 0) {
          out[u] += static_cast<float>(sum);
          continue;
        }
        for (int du = -b.radius; du <= b.radius; ++du) {
          const int col = u + du;
          if (col >= 0 && col < cache.width)
            out[col] += static_cast<float>(sum) * b.along_u.at<float>(du + b.radius);
        }
      }
      row_min = std::min(row_min, v - b.radius);
      row_max = std::max(row_max, v + b.radius);
    }
  }
  if (row_max >= 0 && one_blur && blurs[0].sigma > 0) {
    const int r0 = std::max(0, row_min), r1 = std::min(cache.height, row_max + 1);
    cv::Mat band = laser.rowRange(r0, r1);
    const cv::Mat none = (cv::Mat_<float>(1, 1) << 1.0f);
    cv::sepFilter2D(band.clone(), band, CV_32F, blurs[0].along_u.t(), none, cv::Point(-1, -1), 0.0,
                    cv::BORDER_CONSTANT);
  }
  return laser;
}

FloatImage Renderer::RenderRadiance(int camera, double t, bool lasers_on) const {
  const CameraCache& cache = Cache(camera);
  cv::Mat mean = cache.base.clone();
  if (lasers_on) mean += LaserImage(camera, t, std::nullopt);
  FloatImage image;
  image.width = cache.width;
  image.height = cache.height;
  image.pixels.assign(mean.ptr<float>(0), mean.ptr<float>(0) + mean.total());
  return image;
}

GrayImage Renderer::RenderFrame(int camera, double t, uint64_t frame_index, bool lasers_on) const {
  const CameraCache& cache = Cache(camera);
  const Sensor& sensor = scene_.sensor;
  FrameRandom random(MixSeed(scene_.seed, static_cast<uint64_t>(camera), frame_index));
  // The speckle seed is the frame's first random draw, as it always was.
  std::optional<uint64_t> speckle_seed;
  if (lasers_on && sensor.noise && sensor.speckle_contrast > 0) speckle_seed = random.Next();
  const cv::Mat laser = lasers_on ? LaserImage(camera, t, speckle_seed)
                                  : cv::Mat(cache.height, cache.width, CV_32F, cv::Scalar(0));
  GrayImage image;
  image.width = cache.width;
  image.height = cache.height;
  image.pixels.resize(static_cast<size_t>(cache.width) * cache.height);
  const float read_variance = static_cast<float>(sensor.read_noise_dn * sensor.read_noise_dn);
  const float inverse_gain = static_cast<float>(1.0 / sensor.electrons_per_dn);
  for (int v = 0; v < cache.height; ++v) {
    const float* base_row = cache.base.ptr<float>(v);
    const float* laser_row = laser.ptr<float>(v);
    uint8_t* out = &image.pixels[static_cast<size_t>(v) * cache.width];
    for (int u = 0; u < cache.width; ++u) {
      float value = base_row[u] + laser_row[u];
      if (sensor.noise) {
        value += std::sqrt(value * inverse_gain + read_variance) * random.Normal();
      }
      out[u] = static_cast<uint8_t>(std::clamp(std::lround(value), 0l, 255l));
    }
  }
  return image;
}

std::vector<TruthPeak> Renderer::Truth(int camera, double t) const {
  const Camera& cam = scene_.cameras.at(camera).camera;
  const Eigen::Vector3d center = cam.CenterInWorld();
  std::vector<TruthPeak> peaks;
  std::set<std::tuple<int, int, int, long long>> seen;
  const View views[] = {View::kCenter, View::kLeft, View::kRight, View::kLeftRight,
                        View::kRightLeft};
  const LightSpread& spread = scene_.subject_light_spread;
  const double sheet = scene_.lasers.sheet_sigma_mm,
               spread_sigma = std::hypot(sheet, spread.sigma_mm);
  const double spread_peak =
      spread.Active()
          ? SpreadPeakRatio(sheet, spread_sigma,
                            std::abs(spread.tail_mm) < 0.05 * spread_sigma ? 0.0 : spread.tail_mm)
          : 1.0;

  const Eigen::Vector3d& laser_normal = scene_.lasers.normal;
  // Each laser's light arrives on its own sheet (direct, and through flat mirrors) and on
  // the sheet bent by each bumped mirror (LaserLights): one pass over the meshes each.
  std::vector<int> lights = {-1};
  std::array<double, 2> bend_bound{};  // how far a bumped mirror can bend the light, mm
  for (int m = 0; m < static_cast<int>(scene_.mirrors.size()); ++m) {
    const Mirror& mirror = scene_.mirrors[m];
    if (mirror.bump_mm == 0.0) continue;
    lights.push_back(m);
    // The surface tilts by at most 4 bump / side along each axis; the light turns by
    // twice that, over a path (emitter, mirror, point) far shorter than 4 m.
    const double tilt =
        std::sqrt(2.0) * 4.0 * std::abs(mirror.bump_mm) / std::min(mirror.width, mirror.height);
    bend_bound[m] = 2.0 * tilt * 4000.0 + 1.0;
  }
  for (int k = 0; k < scene_.lasers.count; ++k) {
    const Plane plane = scene_.lasers.PlaneAt(k, t);
    for (const int light_mirror : lights) {
      // Signed distance of a point's light from laser k's sheet.
      auto sheet_distance = [&](const Eigen::Vector3d& x) {
        const double own = plane.SignedDistance(x);
        if (light_mirror < 0 || std::abs(own) > bend_bound[light_mirror]) return own;
        return laser_normal.dot(BumpedLightPath(light_mirror, x).image) + plane.offset;
      };
      for (size_t g = 0; g < materials_.size(); ++g) {
        const enum Material material = materials_[g];
        if (material != Material::kSubject && material != Material::kTarget &&
            material != Material::kPanel)
          continue;
        const TriangleMesh& mesh = tracer_.mesh(static_cast<int>(g));
        for (size_t tri = 0; tri < mesh.triangles.size(); ++tri) {
          const Eigen::Vector3i& ids = mesh.triangles[tri];
          const Eigen::Vector3d p[3] = {mesh.vertices[ids[0]], mesh.vertices[ids[1]],
                                        mesh.vertices[ids[2]]};
          double d[3];
          for (int i = 0; i < 3; ++i) d[i] = sheet_distance(p[i]);
          Eigen::Vector3d ends[2];
          int found = 0;
          for (int i = 0; i < 3 && found < 2; ++i) {
            const int j = (i + 1) % 3;
            if ((d[i] >= 0) != (d[j] >= 0)) {
              double f = d[i] / (d[i] - d[j]);
              if (light_mirror >= 0) {
                // The bent sheet is not a plane: bisect the edge on it.
                double lo = 0.0, hi = 1.0;
                for (int iteration = 0; iteration < 30; ++iteration) {
                  f = 0.5 * (lo + hi);
                  if ((sheet_distance(p[i] + f * (p[j] - p[i])) >= 0) == (d[i] >= 0))
                    lo = f;
                  else
                    hi = f;
                }
              }
              ends[found++] = p[i] + f * (p[j] - p[i]);
            }
          }
          if (found != 2) continue;
          const Eigen::Vector3d normal = mesh.TriangleNormal(static_cast<int>(tri));
          for (View view : views) {
            const std::vector<int> path = MirrorPath(view);
            // The camera sees P at M1(M2(P)); equivalently P from the camera centre M2(M1(C)).
            Eigen::Vector3d virtual_center = center;
            for (int m : path)
              virtual_center = scene_.mirrors[m].plane.ReflectPoint(virtual_center);
            const Eigen::Vector3d mid = 0.5 * (ends[0] + ends[1]);
            // Panels and target quads are seen from either side; closed meshes only from outside.
            if (material == Material::kSubject && normal.dot(virtual_center - mid) <= 0) continue;
            auto project = [&](const Eigen::Vector3d& point) {
              // One bounce through the mirror's true (possibly bumped) surface; two bounces
              // through the planes (a bumped double bounce fails the trace check below).
              Eigen::Vector3d q = point;
              if (path.size() == 1) {
                q = scene_.mirrors[path[0]].ImageOf(point, center);
              } else {
                for (auto it = path.rbegin(); it != path.rend(); ++it)
                  q = scene_.mirrors[*it].plane.ReflectPoint(q);
              }
              return cam.ProjectWorld(q);
            };
            const auto pa = project(ends[0]), pb = project(ends[1]);
            if (!pa || !pb) continue;
            const double u_lo = std::min(pa->x(), pb->x()), u_hi = std::max(pa->x(), pb->x());
            for (int u = static_cast<int>(std::ceil(u_lo)); u <= static_cast<int>(std::floor(u_hi));
                 ++u) {
              if (u < 0 || u >= cam.intrinsics.width) continue;
              // Bisection on the segment for the exact column (the image of a straight
              // segment is curved by lens distortion).
              double lo = 0.0, hi = 1.0;
              const bool rising = pb->x() > pa->x();
              Eigen::Vector3d point = ends[0];
              std::optional<Eigen::Vector2d> pixel;
              for (int iteration = 0; iteration < 60; ++iteration) {
                const double mid_t = 0.5 * (lo + hi);
                point = ends[0] + mid_t * (ends[1] - ends[0]);
                pixel = project(point);
                if (!pixel) break;
                if ((pixel->x() < u) == rising)
                  lo = mid_t;
                else
                  hi = mid_t;
              }
              if (!pixel || !cam.intrinsics.InImage(*pixel)) continue;
              const SurfaceSample s = TracePixel(camera, {u, pixel->y()});
              if (s.view != view || (s.hit.point - point).norm() > 0.05) continue;
              // Only the light of this sheet: direct and flat mirrors, or the bumped mirror's.
              double irradiance = 0.0;
              for (const LaserLight& light : LaserLights(point, s.hit.normal)) {
                if (light.bumped_mirror == light_mirror) irradiance = light.irradiance;
              }
              if (irradiance <= 0) continue;
              const auto key =
                  std::make_tuple(k, static_cast<int>(view), u, std::llround(pixel->y() * 1000));
              if (!seen.insert(key).second) continue;
              TruthPeak peak;
              peak.camera = camera;
              peak.laser = k;
              peak.view = view;
              peak.material = material;
              peak.u = u;
              peak.v = pixel->y();
              peak.point_in_world = point;
              peak.peak_dn = scene_.sensor.laser_dn * scene_.lasers.power * Albedo(s.hit, 1.0) *
                             s.transmission * irradiance *
                             (material == Material::kSubject ? spread_peak : 1.0);
              peaks.push_back(peak);
            }
          }
        }
      }
    }
  }
  std::sort(peaks.begin(), peaks.end(), [](const TruthPeak& a, const TruthPeak& b) {
    return std::tie(a.u, a.v) < std::tie(b.u, b.v);
  });
  return peaks;
}

}  // namespace mirrorscan::virtual_cabinet

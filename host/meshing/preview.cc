#include "host/meshing/preview.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include <embree3/rtcore.h>
#include <opencv2/imgproc.hpp>

namespace mirrorscan::meshing {
namespace {

const cv::Vec3b kBackground(245, 245, 245);
const cv::Scalar kInk(40, 40, 40);

// Tab10-like colours (BGR) for labels.
const cv::Scalar kPalette[] = {{180, 119, 31},  {14, 127, 255}, {44, 160, 44},   {40, 39, 214},
                               {189, 103, 148}, {75, 86, 140},  {194, 119, 227}, {127, 127, 127}};

void ViewAxes(Side side, Eigen::Vector3d* right, Eigen::Vector3d* forward) {
  switch (side) {
    case Side::kFront:
      *forward = {0, 1, 0};
      break;
    case Side::kBack:
      *forward = {0, -1, 0};
      break;
    case Side::kLeft:
      *forward = {1, 0, 0};
      break;
    case Side::kRight:
      *forward = {-1, 0, 0};
      break;
  }
  *right = forward->cross(Eigen::Vector3d::UnitZ());
}

// A round length for the scale bar, at most a third of the image's width.
double BarLength(double width_mm) {
  for (double length : {1000.0, 500.0, 200.0, 100.0, 50.0, 20.0, 10.0}) {
    if (length <= width_mm / 3) return length;
  }
  return 5.0;
}

void DrawAnnotations(cv::Mat* image, const PreviewProjection& projection, Side side,
                     const PreviewOptions& options) {
  const double scale = image->rows / 900.0;
  const int thickness = std::max(1, static_cast<int>(std::lround(2 * scale)));
  const std::string title =
      options.title.empty() ? SideName(side) : options.title + "  " + SideName(side);
  cv::putText(*image, title, {static_cast<int>(12 * scale), static_cast<int>(32 * scale)},
              cv::FONT_HERSHEY_SIMPLEX, 0.8 * scale, kInk, thickness, cv::LINE_AA);
  const double bar_mm = BarLength(image->cols * projection.mm_per_px);
  const int bar_px = static_cast<int>(std::lround(bar_mm / projection.mm_per_px));
  const int x0 = static_cast<int>(15 * scale), y = image->rows - static_cast<int>(20 * scale);
  const int tick = static_cast<int>(6 * scale);
  cv::line(*image, {x0, y}, {x0 + bar_px, y}, kInk, thickness);
  cv::line(*image, {x0, y - tick}, {x0, y + tick}, kInk, thickness);
  cv::line(*image, {x0 + bar_px, y - tick}, {x0 + bar_px, y + tick}, kInk, thickness);
  cv::putText(*image, std::to_string(static_cast<int>(bar_mm)) + " mm",
              {x0, y - static_cast<int>(10 * scale)}, cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale, kInk,
              std::max(1, thickness / 2 + 1), cv::LINE_AA);
}

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  explicit EmbreeScene(const TriangleMesh& mesh) {
    // One thread: previews are small, and the job's thread budget is Poisson's.
    device = rtcNewDevice("threads=1");
    if (!device) throw std::runtime_error("preview: Embree device could not be created");
    scene = rtcNewScene(device);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), mesh.vertices.size()));
    auto* indices = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), mesh.triangles.size()));
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) vertices[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
    }
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<unsigned>(mesh.triangles[i][k]);
    }
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(scene);
  }
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;
};

}  // namespace

const char* SideName(Side side) {
  switch (side) {
    case Side::kFront:
      return "front";
    case Side::kBack:
      return "back";
    case Side::kLeft:
      return "left";
    case Side::kRight:
      return "right";
  }
  return "?";
}

cv::Vec3b PreviewBackground() { return kBackground; }

std::string EmbreeVersion() { return RTC_VERSION_STRING; }

Eigen::Vector2d PreviewProjection::Pixel(const Eigen::Vector3d& point_in_world) const {
  const Eigen::Vector3d d = point_in_world - origin;
  return {d.dot(right) / mm_per_px, -d.dot(up) / mm_per_px};
}

PreviewProjection FrameView(const Eigen::AlignedBox3d& bounds, Side side, int height_px) {
  if (height_px < 64 || height_px > 8192) {
    throw std::invalid_argument("preview: height must be in [64, 8192] px");
  }
  PreviewProjection projection;
  ViewAxes(side, &projection.right, &projection.forward);
  projection.up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d center = bounds.center();
  const double height_mm = std::max(bounds.sizes().z(), 1.0) * 1.12;
  const double radius_mm = std::max(bounds.sizes().head<2>().norm() / 2, 1.0) * 1.1;
  projection.mm_per_px = height_mm / height_px;
  projection.origin = center - projection.right * radius_mm + projection.up * (height_mm / 2);
  return projection;
}

PreviewImage RenderMeshPreview(const TriangleMesh& mesh, Side side, const PreviewOptions& options) {
  if (mesh.triangles.empty()) throw std::invalid_argument("preview: the mesh has no triangles");
  Eigen::AlignedBox3d bounds;
  for (const Eigen::Vector3d& v : mesh.vertices) bounds.extend(v);
  PreviewImage out;
  out.projection = FrameView(bounds, side, options.height_px);
  const PreviewProjection& p = out.projection;
  const double radius_mm = (bounds.center() - p.origin).dot(p.right);
  const int width = static_cast<int>(std::ceil(2 * radius_mm / p.mm_per_px));
  out.image = cv::Mat(options.height_px, width, CV_8UC3, cv::Scalar(kBackground));

  const EmbreeScene embree(mesh);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const double depth_mm = bounds.diagonal().norm() + 10.0;
  const Eigen::Vector3d start =
      p.origin - p.forward * (p.forward.dot(p.origin - bounds.center()) + depth_mm);
  const Eigen::Vector3d light = (-p.forward + 0.5 * p.up - 0.3 * p.right).normalized();
  const bool smooth = mesh.vertex_normals.size() == mesh.vertices.size();
  for (int row = 0; row < out.image.rows; ++row) {
    auto* pixels = out.image.ptr<cv::Vec3b>(row);
    for (int col = 0; col < out.image.cols; ++col) {
      const Eigen::Vector3d origin =
          start + p.right * ((col + 0.5) * p.mm_per_px) - p.up * ((row + 0.5) * p.mm_per_px);
      RTCRayHit ray{};
      ray.ray.org_x = static_cast<float>(origin.x());
      ray.ray.org_y = static_cast<float>(origin.y());
      ray.ray.org_z = static_cast<float>(origin.z());
      ray.ray.dir_x = static_cast<float>(p.forward.x());
      ray.ray.dir_y = static_cast<float>(p.forward.y());
      ray.ray.dir_z = static_cast<float>(p.forward.z());
      ray.ray.tnear = 0.0f;
      ray.ray.tfar = std::numeric_limits<float>::infinity();
      ray.ray.mask = 0xFFFFFFFFu;
      ray.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(embree.scene, &context, &ray);
      if (ray.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      const Eigen::Vector3i& t = mesh.triangles[ray.hit.primID];
      Eigen::Vector3d normal;
      if (smooth) {
        normal = (1 - ray.hit.u - ray.hit.v) * mesh.vertex_normals[t[0]] +
                 ray.hit.u * mesh.vertex_normals[t[1]] + ray.hit.v * mesh.vertex_normals[t[2]];
      } else {
        normal = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                     .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
      }
      normal.normalize();
      // The inside of the surface, seen through a hole, in a cooler tone.
      const bool inside = normal.dot(p.forward) > 0;
      if (inside) normal = -normal;
      const double shade = 0.25 + 0.75 * std::max(0.0, normal.dot(light));
      const cv::Vec3d base = inside ? cv::Vec3d(200, 150, 120) : cv::Vec3d(185, 200, 220);
      pixels[col] = cv::Vec3b(cv::saturate_cast<uint8_t>(base[0] * shade),
                              cv::saturate_cast<uint8_t>(base[1] * shade),
                              cv::saturate_cast<uint8_t>(base[2] * shade));
    }
  }
  DrawAnnotations(&out.image, p, side, options);
  return out;
}

PreviewImage RenderCloudPreview(const PointCloud& cloud, ColourBy colour_by,
                                const std::vector<std::string>& label_names, Side side,
                                const PreviewOptions& options,
                                std::optional<Eigen::AlignedBox3d> bounds) {
  if (cloud.points.empty()) throw std::invalid_argument("preview: the cloud is empty");
  auto point_at = [&](size_t i) { return cloud.points[i].point_in_world.cast<double>().eval(); };
  if (!bounds) {
    bounds.emplace();
    for (size_t i = 0; i < cloud.points.size(); ++i) bounds->extend(point_at(i));
  }
  PreviewImage out;
  out.projection = FrameView(*bounds, side, options.height_px);
  const PreviewProjection& p = out.projection;
  const double radius_mm = (bounds->center() - p.origin).dot(p.right);
  const int width = static_cast<int>(std::ceil(2 * radius_mm / p.mm_per_px));
  out.image = cv::Mat(options.height_px, width, CV_8UC3, cv::Scalar(kBackground));

  std::vector<double> depth(cloud.points.size());
  for (size_t i = 0; i < depth.size(); ++i) depth[i] = point_at(i).dot(p.forward);
  std::vector<size_t> order(cloud.points.size());
  std::iota(order.begin(), order.end(), 0);
  // Far first, so nearer dots cover them; ties in index order (the same image every run).
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return depth[a] > depth[b]; });
  const int radius_px = std::max(1, static_cast<int>(std::lround(1.5 / p.mm_per_px)));
  constexpr int kPalette_size = sizeof(kPalette) / sizeof(kPalette[0]);
  for (size_t i : order) {
    const CloudPoint& point = cloud.points[i];
    const Eigen::Vector2d pixel = p.Pixel(point_at(i));
    const double facing = -point.normal.cast<double>().dot(p.forward);
    const double shade = 0.35 + 0.65 * std::max(0.0, facing);
    const int label = colour_by == ColourBy::kView ? static_cast<int>(point.view)
                                                   : static_cast<int>(point.camera);
    const cv::Scalar colour = kPalette[label % kPalette_size] * shade;
    cv::circle(out.image,
               {static_cast<int>(std::lround(pixel.x())), static_cast<int>(std::lround(pixel.y()))},
               radius_px, colour, cv::FILLED, cv::LINE_8);
  }
  const double scale = out.image.rows / 900.0;
  for (size_t k = 0; k < label_names.size(); ++k) {
    const int y = static_cast<int>((60 + 28 * k) * scale);
    const int x = static_cast<int>(14 * scale);
    cv::rectangle(out.image, {x, y - static_cast<int>(14 * scale)},
                  {x + static_cast<int>(16 * scale), y + static_cast<int>(2 * scale)},
                  kPalette[k % kPalette_size], cv::FILLED);
    cv::putText(out.image, label_names[k], {x + static_cast<int>(24 * scale), y},
                cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale, kInk, std::max(1, static_cast<int>(scale)),
                cv::LINE_AA);
  }
  DrawAnnotations(&out.image, p, side, options);
  return out;
}

}  // namespace mirrorscan::meshing

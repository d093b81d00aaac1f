#include "boards/virtual/raytracer.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace mirrorscan::virtual_cabinet {

struct RayTracer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  bool committed = false;
};

namespace {

void ThrowOnDeviceError(RTCDevice device, const char* what) {
  const RTCError error = rtcGetDeviceError(device);
  if (error != RTC_ERROR_NONE) {
    throw std::runtime_error(std::string("Embree: ") + what + " failed (error " +
                             std::to_string(static_cast<int>(error)) + ")");
  }
}

RTCRay MakeRay(const Ray3d& ray, double t_min, double t_max) {
  RTCRay r{};
  r.org_x = static_cast<float>(ray.origin.x());
  r.org_y = static_cast<float>(ray.origin.y());
  r.org_z = static_cast<float>(ray.origin.z());
  r.dir_x = static_cast<float>(ray.direction.x());
  r.dir_y = static_cast<float>(ray.direction.y());
  r.dir_z = static_cast<float>(ray.direction.z());
  r.tnear = static_cast<float>(t_min);
  r.tfar =
      std::isfinite(t_max) ? static_cast<float>(t_max) : std::numeric_limits<float>::infinity();
  r.mask = 0xFFFFFFFFu;
  r.flags = 0;
  r.time = 0.0f;
  return r;
}

}  // namespace

RayTracer::RayTracer() : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice("threads=1");
  if (!impl_->device) throw std::runtime_error("Embree: cannot create device");
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
}

RayTracer::~RayTracer() {
  if (impl_->scene) rtcReleaseScene(impl_->scene);
  if (impl_->device) rtcReleaseDevice(impl_->device);
}

int RayTracer::AddMesh(const TriangleMesh& mesh) {
  if (impl_->committed) throw std::logic_error("RayTracer::AddMesh after Commit");
  RTCGeometry geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                              3 * sizeof(float), std::max<size_t>(mesh.vertices.size(), 1)));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              3 * sizeof(unsigned), std::max<size_t>(mesh.triangles.size(), 1)));
  ThrowOnDeviceError(impl_->device, "geometry buffers");
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int c = 0; c < 3; ++c) vertices[3 * i + c] = static_cast<float>(mesh.vertices[i][c]);
  }
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int c = 0; c < 3; ++c) indices[3 * i + c] = static_cast<unsigned>(mesh.triangles[i][c]);
  }
  if (mesh.triangles.empty()) {  // Embree needs a buffer; a degenerate triangle never hits.
    vertices[0] = vertices[1] = vertices[2] = 0.0f;
    indices[0] = indices[1] = indices[2] = 0;
  }
  rtcCommitGeometry(geometry);
  const unsigned id = rtcAttachGeometry(impl_->scene, geometry);
  rtcReleaseGeometry(geometry);
  if (id != meshes_.size()) throw std::logic_error("Embree geometry ids out of step");
  meshes_.push_back(mesh);
  return static_cast<int>(id);
}

void RayTracer::Commit() {
  rtcCommitScene(impl_->scene);
  ThrowOnDeviceError(impl_->device, "scene commit");
  impl_->committed = true;
}

std::optional<RayHit> RayTracer::Intersect(const Ray3d& ray, double t_min, double t_max) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit ray_hit{};
  ray_hit.ray = MakeRay(ray, t_min, t_max);
  ray_hit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  ray_hit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &ray_hit);
  if (ray_hit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;

  RayHit hit;
  hit.geometry = static_cast<int>(ray_hit.hit.geomID);
  hit.triangle = static_cast<int>(ray_hit.hit.primID);
  const TriangleMesh& mesh = meshes_[hit.geometry];
  const Eigen::Vector3i& tri = mesh.triangles[hit.triangle];
  const Eigen::Vector3d& a = mesh.vertices[tri[0]];
  hit.normal = mesh.TriangleNormal(hit.triangle);
  const double denominator = hit.normal.dot(ray.direction);
  hit.t = std::abs(denominator) > 1e-12 ? hit.normal.dot(a - ray.origin) / denominator
                                        : static_cast<double>(ray_hit.ray.tfar);
  hit.point = ray.At(hit.t);
  return hit;
}

bool RayTracer::Occluded(const Ray3d& ray, double t_min, double t_max) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r = MakeRay(ray, t_min, t_max);
  rtcOccluded1(impl_->scene, &context, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit.
}

}  // namespace mirrorscan::virtual_cabinet

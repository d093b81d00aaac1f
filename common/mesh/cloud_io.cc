#include "common/mesh/cloud_io.h"

#include <bit>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <system_error>
#include <vector>

#include "common/mesh/ply.h"

namespace mirrorscan {
namespace {

constexpr const char* kProperties =
    "property float x\nproperty float y\nproperty float z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "property uchar camera\nproperty uchar view\nproperty uchar laser\n"
    "property uint frame\nproperty float u\nproperty float v\nproperty float confidence\n"
    "property uchar rule\n";
constexpr size_t kRecordSize = 6 * 4 + 3 + 4 + 3 * 4 + 1;

// An integral field's value, clamped to its type (NaN: 0).
template <typename T>
T Integral(double value) {
  if (!(value >= 0.0)) return T{0};
  return value >= static_cast<double>(std::numeric_limits<T>::max()) ? std::numeric_limits<T>::max()
                                                                     : static_cast<T>(value);
}

template <typename T>
char* Put(char* at, T value) {
  std::memcpy(at, &value, sizeof value);
  return at + sizeof value;
}

}  // namespace

void WritePointCloud(const std::filesystem::path& file, const PointCloud& cloud) {
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes little-endian");
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) throw MeshIoError(file.string() + ": cannot write");
  out << "ply\nformat binary_little_endian 1.0\ncomment mirrorscan reconstruct\n"
      << "comment view: 0 center, 1 left, 2 right, 3 left-right, 4 right-left\n"
      << "comment rule: 0 cylinder, 1 volume, 2 column count, 3 label vote\n"
      << "element vertex " << cloud.points.size() << "\n"
      << kProperties << "end_header\n";
  std::vector<char> buffer(kRecordSize * cloud.points.size());
  char* at = buffer.data();
  for (const CloudPoint& p : cloud.points) {
    for (int i = 0; i < 3; ++i) at = Put(at, p.point_in_world[i]);
    for (int i = 0; i < 3; ++i) at = Put(at, p.normal[i]);
    at = Put(at, p.camera);
    at = Put(at, static_cast<uint8_t>(p.view));
    at = Put(at, p.laser);
    at = Put(at, p.frame);
    at = Put(at, p.u);
    at = Put(at, p.v);
    at = Put(at, p.confidence);
    at = Put(at, static_cast<uint8_t>(p.rule));
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  if (!out.flush()) throw MeshIoError(file.string() + ": cannot write");
}

PointCloud ReadPointCloud(const std::filesystem::path& file, bool require_normals) {
  std::error_code error;
  if (!std::filesystem::exists(file, error)) throw MeshIoError(file.string() + ": no such file");
  if (LowerCaseExtension(file) != ".ply")
    throw MeshIoError(file.string() + ": expected a .ply cloud");
  const ply::Reader reader(file);
  const int vertex_element = reader.Find("vertex");
  if (vertex_element < 0) throw MeshIoError(file.string() + ": the PLY file has no vertex element");
  const ply::Element& vertex = reader.elements()[vertex_element];
  // Each field's property index, or -1 when the file lacks it.
  enum Field {
    kX,
    kY,
    kZ,
    kNx,
    kNy,
    kNz,
    kCamera,
    kView,
    kLaser,
    kFrame,
    kU,
    kV,
    kConfidence,
    kRule
  };
  static const char* kNames[] = {"x",    "y",     "z",     "nx", "ny", "nz",         "camera",
                                 "view", "laser", "frame", "u",  "v",  "confidence", "rule"};
  int at[std::size(kNames)];
  for (size_t f = 0; f < std::size(kNames); ++f) {
    at[f] = vertex.Find(kNames[f]);
    if (at[f] >= 0 && vertex.properties[at[f]].is_list) {
      throw MeshIoError(file.string() + ": vertex property " + kNames[f] + " is a list");
    }
  }
  if (at[kX] < 0 || at[kY] < 0 || at[kZ] < 0) {
    throw MeshIoError(file.string() + ": the points have no x, y, z");
  }
  const bool normals = at[kNx] >= 0 && at[kNy] >= 0 && at[kNz] >= 0;
  if (require_normals && !normals && vertex.count > 0) {
    throw MeshIoError(file.string() + ": the cloud has no normals (nx, ny, nz)");
  }
  PointCloud cloud;
  cloud.points.reserve(vertex.count);
  reader.ReadRows([&](size_t element, size_t, const ply::Row& row) {
    if (static_cast<int>(element) != vertex_element) return;
    auto value = [&](Field f) { return at[f] >= 0 ? row[at[f]][0] : 0.0; };
    CloudPoint& p = cloud.points.emplace_back();
    p.point_in_world = Eigen::Vector3d(value(kX), value(kY), value(kZ)).cast<float>();
    if (normals) p.normal = Eigen::Vector3d(value(kNx), value(kNy), value(kNz)).cast<float>();
    p.camera = Integral<uint8_t>(value(kCamera));
    p.view = static_cast<PointView>(Integral<uint8_t>(value(kView)));
    p.laser = Integral<uint8_t>(value(kLaser));
    p.frame = Integral<uint32_t>(value(kFrame));
    p.u = static_cast<float>(value(kU));
    p.v = static_cast<float>(value(kV));
    p.confidence = static_cast<float>(value(kConfidence));
    p.rule = static_cast<DecidedBy>(Integral<uint8_t>(value(kRule)));
  });
  return cloud;
}

}  // namespace mirrorscan

// Binary PLY of the reconstructed cloud (the layout WritePly's comment in reconstruct.h
// gives).
#include <bit>
#include <cstring>
#include <fstream>
#include <sstream>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {

namespace {

constexpr const char* kProperties =
    "property float x\nproperty float y\nproperty float z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "property uchar camera\nproperty uchar view\nproperty uchar laser\n"
    "property uint frame\nproperty float u\nproperty float v\nproperty float confidence\n"
    "property uchar rule\n";
constexpr size_t kRecordSize = 6 * 4 + 3 + 4 + 3 * 4 + 1;

template <typename T>
char* Put(char* at, T value) {
  std::memcpy(at, &value, sizeof value);
  return at + sizeof value;
}
template <typename T>
const char* Get(const char* at, T* value) {
  std::memcpy(value, at, sizeof *value);
  return at + sizeof *value;
}

}  // namespace

void WritePly(const std::filesystem::path& path, const PointCloud& cloud) {
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes little-endian");
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
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
  if (!out.flush()) throw std::runtime_error(path.string() + ": cannot write");
}

PointCloud ReadPly(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot read");
  std::string line, properties;
  size_t count = 0;
  bool binary = false;
  if (!std::getline(in, line) || line != "ply")
    throw std::runtime_error(path.string() + ": not a PLY file");
  while (std::getline(in, line) && line != "end_header") {
    if (line == "format binary_little_endian 1.0") binary = true;
    if (line.rfind("element vertex ", 0) == 0) count = std::stoull(line.substr(15));
    if (line.rfind("property ", 0) == 0) properties += line + "\n";
  }
  if (!binary || properties != kProperties)
    throw std::runtime_error(path.string() + ": not a mirrorscan point cloud (other PLY layout)");
  std::vector<char> buffer(kRecordSize * count);
  if (!in.read(buffer.data(), static_cast<std::streamsize>(buffer.size())))
    throw std::runtime_error(path.string() + ": cut off (header says " + std::to_string(count) +
                             " points)");
  PointCloud cloud;
  cloud.points.resize(count);
  const char* at = buffer.data();
  for (CloudPoint& p : cloud.points) {
    for (int i = 0; i < 3; ++i) at = Get(at, &p.point_in_world[i]);
    for (int i = 0; i < 3; ++i) at = Get(at, &p.normal[i]);
    uint8_t view = 0;
    at = Get(at, &p.camera);
    at = Get(at, &view);
    p.view = static_cast<PointView>(view);
    at = Get(at, &p.laser);
    at = Get(at, &p.frame);
    at = Get(at, &p.u);
    at = Get(at, &p.v);
    at = Get(at, &p.confidence);
    uint8_t rule = 0;
    at = Get(at, &rule);
    p.rule = static_cast<DecidedBy>(rule);
  }
  return cloud;
}

}  // namespace mirrorscan::reconstruction

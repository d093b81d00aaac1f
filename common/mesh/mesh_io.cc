#include "common/mesh/mesh_io.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <system_error>
#include <tuple>
#include <vector>

#include "common/mesh/ply.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little, "mesh files are written little-endian");

void CheckExtension(const fs::path& file) {
  const std::string ext = LowerCaseExtension(file);
  if (ext != ".ply" && ext != ".obj" && ext != ".stl") {
    throw MeshIoError(file.string() + ": unsupported mesh format \"" + ext +
                      "\" (expected .ply, .obj or .stl)");
  }
}

std::string ReadWhole(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshIoError(file.string() + ": cannot read");
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return std::move(bytes).str();
}

// Triangles of a polygon's corners, as a fan from the first.
void AddPolygon(const std::vector<int>& corners, TriangleMesh* mesh) {
  for (size_t k = 2; k < corners.size(); ++k) {
    mesh->triangles.emplace_back(corners[0], corners[k - 1], corners[k]);
  }
}

TriangleMesh ReadPly(const fs::path& file) {
  const ply::Reader reader(file);
  const int vertex_element = reader.Find("vertex");
  if (vertex_element < 0) throw MeshIoError(file.string() + ": the PLY file has no vertex element");
  const ply::Element& vertex = reader.elements()[vertex_element];
  const int x = vertex.Find("x"), y = vertex.Find("y"), z = vertex.Find("z");
  if (x < 0 || y < 0 || z < 0) throw MeshIoError(file.string() + ": the vertices have no x, y, z");
  const int nx = vertex.Find("nx"), ny = vertex.Find("ny"), nz = vertex.Find("nz");
  const bool normals = nx >= 0 && ny >= 0 && nz >= 0;
  const int face_element = reader.Find("face");
  int indices = -1;
  if (face_element >= 0) {
    const ply::Element& face = reader.elements()[face_element];
    indices = face.Find("vertex_indices");
    if (indices < 0) indices = face.Find("vertex_index");
    if (indices < 0 || !face.properties[indices].is_list) {
      throw MeshIoError(file.string() + ": the faces have no vertex_indices list");
    }
  }
  TriangleMesh mesh;
  mesh.vertices.reserve(vertex.count);
  if (normals) mesh.vertex_normals.reserve(vertex.count);
  std::vector<int> corners;
  reader.ReadRows([&](size_t element, size_t, const ply::Row& row) {
    if (static_cast<int>(element) == vertex_element) {
      mesh.vertices.emplace_back(row[x][0], row[y][0], row[z][0]);
      if (normals) mesh.vertex_normals.emplace_back(row[nx][0], row[ny][0], row[nz][0]);
    } else if (static_cast<int>(element) == face_element) {
      corners.assign(row[indices].begin(), row[indices].end());
      AddPolygon(corners, &mesh);
    }
  });
  return mesh;
}

// The numbers of an OBJ line after its keyword.
bool ParseNumber(std::string_view text, double* value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return error == std::errc() && end == text.data() + text.size();
}

TriangleMesh ReadObj(const fs::path& file) {
  std::istringstream in(ReadWhole(file));
  TriangleMesh mesh;
  std::string line, word;
  std::vector<int> corners;
  for (int number = 1; std::getline(in, line); ++number) {
    auto bad = [&](const std::string& why) {
      return MeshIoError(file.string() + ": OBJ line " + std::to_string(number) + ": " + why);
    };
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "v") {
      Eigen::Vector3d v;
      for (int k = 0; k < 3; ++k) {
        if (!(words >> word) || !ParseNumber(word, &v[k])) throw bad("a vertex needs x y z");
      }
      mesh.vertices.push_back(v);
    } else if (keyword == "f") {
      corners.clear();
      while (words >> word) {
        // v, v/vt, v/vt/vn or v//vn: the vertex is the first number.
        const std::string index_text = word.substr(0, word.find('/'));
        double index = 0.0;
        if (!ParseNumber(index_text, &index) || index == 0 || index != std::floor(index)) {
          throw bad("bad face corner \"" + word + "\"");
        }
        // Negative: counted back from the last vertex so far.
        const double base = index < 0 ? static_cast<double>(mesh.vertices.size()) : -1.0;
        corners.push_back(static_cast<int>(base + index));
      }
      if (corners.size() < 3) throw bad("a face needs three corners");
      AddPolygon(corners, &mesh);
    }
  }
  return mesh;
}

// Corners at the same position become one vertex, numbered in order of first use.
struct CornerWelder {
  TriangleMesh mesh;
  std::map<std::tuple<double, double, double>, int> index;
  int Add(const Eigen::Vector3d& corner) {
    const auto [it, added] =
        index.emplace(std::tuple(corner.x(), corner.y(), corner.z()), mesh.vertices.size());
    if (added) mesh.vertices.push_back(corner);
    return it->second;
  }
};

TriangleMesh ReadStl(const fs::path& file) {
  const std::string bytes = ReadWhole(file);
  CornerWelder welder;
  uint32_t count = 0;
  if (bytes.size() >= 84) std::memcpy(&count, bytes.data() + 80, 4);
  // A binary file's size is exact; an ASCII one starts with "solid" (and so may a binary
  // file's free header).
  if (bytes.size() >= 84 && bytes.size() == 84 + 50 * static_cast<uint64_t>(count)) {
    for (uint32_t t = 0; t < count; ++t) {
      const char* facet = bytes.data() + 84 + 50 * static_cast<size_t>(t);
      Eigen::Vector3i triangle;
      for (int k = 0; k < 3; ++k) {
        float corner[3];
        std::memcpy(corner, facet + 12 * (k + 1), sizeof corner);
        triangle[k] = welder.Add(Eigen::Vector3f(corner[0], corner[1], corner[2]).cast<double>());
      }
      welder.mesh.triangles.push_back(triangle);
    }
    return std::move(welder.mesh);
  }
  std::istringstream in(bytes);
  std::string word;
  if (!(in >> word) || word != "solid") {
    throw MeshIoError(file.string() + ": neither a binary STL (" + std::to_string(bytes.size()) +
                      " bytes) nor an ASCII one (\"solid\")");
  }
  std::vector<int> corners;
  while (in >> word) {
    if (word == "vertex") {
      Eigen::Vector3d corner;
      std::string text;
      for (int k = 0; k < 3; ++k) {
        if (!(in >> text) || !ParseNumber(text, &corner[k])) {
          throw MeshIoError(file.string() + ": ASCII STL vertex " +
                            std::to_string(corners.size() + 3 * welder.mesh.triangles.size()) +
                            " needs x y z");
        }
      }
      corners.push_back(welder.Add(corner));
    } else if (word == "endloop") {
      AddPolygon(corners, &welder.mesh);
      corners.clear();
    }
  }
  return std::move(welder.mesh);
}

void Validate(const fs::path& file, const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) throw MeshIoError(file.string() + ": mesh has no triangles");
  const int vertex_count = static_cast<int>(mesh.vertices.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= vertex_count) {
      throw MeshIoError(file.string() + ": a triangle refers to a missing vertex");
    }
  }
  for (const Eigen::Vector3d& v : mesh.vertices) {
    if (!v.allFinite()) throw MeshIoError(file.string() + ": a vertex is not finite");
  }
}

template <typename T>
void Put(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof value);
}

std::string PlyBytes(const TriangleMesh& mesh) {
  const bool normals = mesh.HasVertexNormals();
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\ncomment Created by Open3D\n"
         << "element vertex " << mesh.vertices.size() << "\n"
         << "property double x\nproperty double y\nproperty double z\n"
         << (normals ? "property double nx\nproperty double ny\nproperty double nz\n" : "")
         << "element face " << mesh.triangles.size() << "\n"
         << "property list uchar uint vertex_indices\nend_header\n";
  std::string out = std::move(header).str();
  out.reserve(out.size() + mesh.vertices.size() * (normals ? 48 : 24) + mesh.triangles.size() * 13);
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) Put(&out, mesh.vertices[i][k]);
    if (normals) {
      for (int k = 0; k < 3; ++k) Put(&out, mesh.vertex_normals[i][k]);
    }
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    Put(&out, uint8_t{3});
    for (int k = 0; k < 3; ++k) Put(&out, static_cast<uint32_t>(t[k]));
  }
  return out;
}

std::string ObjBytes(const TriangleMesh& mesh, const fs::path& file) {
  const bool normals = mesh.HasVertexNormals();
  // The default stream format (six significant digits), as Open3D writes.
  std::ostringstream out;
  out << "# Created by Open3D \n# object name: " << file.stem().string()
      << "\n# number of vertices: " << mesh.vertices.size()
      << "\n# number of triangles: " << mesh.triangles.size() << "\n";
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    out << "v " << v[0] << " " << v[1] << " " << v[2] << "\n";
    if (normals) {
      const Eigen::Vector3d& n = mesh.vertex_normals[i];
      out << "vn " << n[0] << " " << n[1] << " " << n[2] << "\n";
    }
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    out << "f";
    for (int k = 0; k < 3; ++k) {
      out << " " << t[k] + 1;
      if (normals) out << "//" << t[k] + 1;
    }
    out << "\n";
  }
  return std::move(out).str();
}

std::string StlBytes(const TriangleMesh& mesh) {
  std::string out(80, '\0');
  const char kHeader[] = "Created by Open3D";
  std::memcpy(out.data(), kHeader, sizeof kHeader - 1);
  Put(&out, static_cast<uint32_t>(mesh.triangles.size()));
  out.reserve(84 + 50 * mesh.triangles.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    // Normalised as Open3D does: a degenerate triangle's zero normal stays zero.
    Eigen::Vector3d normal = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                                 .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
    normal.normalize();
    if (std::isnan(normal[0])) normal = Eigen::Vector3d::UnitZ();
    for (int k = 0; k < 3; ++k) Put(&out, static_cast<float>(normal[k]));
    for (int corner = 0; corner < 3; ++corner) {
      for (int k = 0; k < 3; ++k) Put(&out, static_cast<float>(mesh.vertices[t[corner]][k]));
    }
    Put(&out, uint16_t{0});
  }
  return out;
}

}  // namespace

std::string LowerCaseExtension(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

TriangleMesh ReadTriangleMesh(const fs::path& file) {
  CheckExtension(file);
  std::error_code error;
  if (!fs::exists(file, error)) throw MeshIoError(file.string() + ": no such file");
  if (!fs::is_regular_file(file, error)) throw MeshIoError(file.string() + ": not a regular file");
  const std::string ext = LowerCaseExtension(file);
  TriangleMesh mesh = ext == ".ply" ? ReadPly(file) : ext == ".obj" ? ReadObj(file) : ReadStl(file);
  Validate(file, mesh);
  return mesh;
}

void WriteTriangleMesh(const TriangleMesh& mesh, const fs::path& file) {
  CheckExtension(file);
  if (mesh.triangles.empty()) throw MeshIoError(file.string() + ": no triangles to write");
  const std::string ext = LowerCaseExtension(file);
  const std::string bytes = ext == ".ply"   ? PlyBytes(mesh)
                            : ext == ".obj" ? ObjBytes(mesh, file)
                                            : StlBytes(mesh);
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.flush()) throw MeshIoError(file.string() + ": cannot write");
}

}  // namespace mirrorscan

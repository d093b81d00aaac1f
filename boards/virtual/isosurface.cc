#include "boards/virtual/isosurface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include "common/parallel/parallel_for.h"

namespace mirrorscan::virtual_cabinet {
namespace {

constexpr int kBlock = 4;  // cells per block side

// The six tetrahedra of a cell, as corner indices (bit 0: x, bit 1: y, bit 2: z), each a
// path 0 -> 7 along the axes in one order (the Kuhn triangulation).
constexpr std::array<std::array<int, 4>, 6> kTetrahedra = {{
    {0, 1, 3, 7},
    {0, 1, 5, 7},
    {0, 2, 3, 7},
    {0, 2, 6, 7},
    {0, 4, 5, 7},
    {0, 4, 6, 7},
}};

struct Grid {
  Eigen::Vector3d origin;
  double cell = 0;
  Eigen::Vector3i points;  // grid points per axis

  int64_t Key(const Eigen::Vector3i& p) const {
    return (static_cast<int64_t>(p.z()) * points.y() + p.y()) * points.x() + p.x();
  }
  Eigen::Vector3d Position(const Eigen::Vector3i& p) const {
    return origin + cell * p.cast<double>();
  }
};

struct EdgeKeyHash {
  size_t operator()(const std::pair<int64_t, int64_t>& e) const {
    return std::hash<int64_t>()(e.first * 1000003 ^ e.second);
  }
};

// The field's zero on the segment a (value fa) to b (the other side), by regula falsi with
// the Illinois fix, kept 2 % of the segment clear of its ends: a vertex closer to a grid
// point than that makes slivers that floating-point intersection tests (Open3D's) take for
// crossings. The surface is then at most 2 % of a cell (0.08 mm at 4 mm) off there.
Eigen::Vector3d ZeroOnEdge(const std::function<double(const Eigen::Vector3d&)>& field,
                           const Eigen::Vector3d& a, double fa, const Eigen::Vector3d& b,
                           double fb) {
  double lo = 0, hi = 1, f_lo = fa, f_hi = fb;
  double t = fa / (fa - fb);
  int side = 0;
  for (int i = 0; i < 30; ++i) {
    t = lo + (hi - lo) * f_lo / (f_lo - f_hi);
    const double ft = field(a + t * (b - a));
    if (std::abs(ft) < 1e-7) break;
    if ((ft < 0) == (f_lo < 0)) {
      lo = t;
      f_lo = ft;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = t;
      f_hi = ft;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
  }
  t = std::clamp(t, 0.02, 0.98);
  return a + t * (b - a);
}

}  // namespace

TriangleMesh MeshIsosurface(const std::function<double(const Eigen::Vector3d&)>& field,
                            const Eigen::AlignedBox3d& box, double cell_mm, double band_mm,
                            int threads) {
  if (!(cell_mm > 0) || box.isEmpty()) throw std::invalid_argument("isosurface: bad grid");
  Grid grid;
  grid.cell = cell_mm;
  const Eigen::Vector3d size = box.sizes();
  const Eigen::Vector3i blocks =
      ((size / (cell_mm * kBlock)).array().ceil().cast<int>() + 2).matrix();
  grid.points = blocks * kBlock + Eigen::Vector3i::Ones();
  grid.origin = box.center() - 0.5 * cell_mm * kBlock * blocks.cast<double>();

  // Block corners first: a block is meshed unless all its corners are beyond the band on
  // one side.
  const Eigen::Vector3i corners = blocks + Eigen::Vector3i::Ones();
  const size_t corner_count = static_cast<size_t>(corners.prod());
  std::vector<float> corner_value(corner_count);
  ParallelFor(corner_count, threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const int x = static_cast<int>(i % corners.x());
      const int y = static_cast<int>((i / corners.x()) % corners.y());
      const int z = static_cast<int>(i / (static_cast<size_t>(corners.x()) * corners.y()));
      corner_value[i] = static_cast<float>(field(grid.Position(Eigen::Vector3i(x, y, z) * kBlock)));
    }
  });
  auto corner_at = [&](int x, int y, int z) {
    return corner_value[(static_cast<size_t>(z) * corners.y() + y) * corners.x() + x];
  };
  std::vector<Eigen::Vector3i> active;
  for (int z = 0; z < blocks.z(); ++z)
    for (int y = 0; y < blocks.y(); ++y)
      for (int x = 0; x < blocks.x(); ++x) {
        bool inside = false, outside = false, near = false;
        for (int c = 0; c < 8; ++c) {
          const float v = corner_at(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
          (v < 0 ? inside : outside) = true;
          near |= std::abs(v) < band_mm;
        }
        if (near || (inside && outside)) active.emplace_back(x, y, z);
      }
  const int edge = kBlock + 1;
  auto local_index = [edge](int x, int y, int z) { return (z * edge + y) * edge + x; };

  // Per block: its grid values and the tetrahedra's surface pieces as edges (pairs of grid
  // point keys), oriented later.
  struct Piece {
    std::array<std::pair<int64_t, int64_t>, 3> edges;
    Eigen::Vector3d outward;  // from the tetrahedron's inside corners to its outside ones
  };
  std::vector<std::vector<Piece>> pieces(active.size());
  std::vector<std::unordered_map<int64_t, float>> values(active.size());
  ParallelFor(active.size(), threads, [&](size_t begin, size_t end) {
    std::vector<float> value(edge * edge * edge);
    for (size_t b = begin; b < end; ++b) {
      const Eigen::Vector3i first = active[b] * kBlock;
      for (int z = 0; z < edge; ++z)
        for (int y = 0; y < edge; ++y)
          for (int x = 0; x < edge; ++x)
            value[local_index(x, y, z)] =
                static_cast<float>(field(grid.Position(first + Eigen::Vector3i(x, y, z))));
      for (int z = 0; z < kBlock; ++z)
        for (int y = 0; y < kBlock; ++y)
          for (int x = 0; x < kBlock; ++x) {
            std::array<Eigen::Vector3i, 8> corner;
            std::array<float, 8> v;
            for (int c = 0; c < 8; ++c) {
              corner[c] = Eigen::Vector3i(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
              v[c] = value[local_index(corner[c].x(), corner[c].y(), corner[c].z())];
            }
            bool any_in = false, any_out = false;
            for (float f : v) (f < 0 ? any_in : any_out) = true;
            if (!any_in || !any_out) continue;
            for (const auto& tet : kTetrahedra) {
              std::array<int, 4> in{}, out{};
              int n_in = 0, n_out = 0;
              for (int c : tet) (v[c] < 0 ? in[n_in++] : out[n_out++]) = c;
              if (n_in == 0 || n_out == 0) continue;
              Eigen::Vector3d in_mean = Eigen::Vector3d::Zero(), out_mean = in_mean;
              for (int i = 0; i < n_in; ++i) in_mean += corner[in[i]].cast<double>() / n_in;
              for (int i = 0; i < n_out; ++i) out_mean += corner[out[i]].cast<double>() / n_out;
              auto key = [&](int a, int c) {
                const int64_t ka = grid.Key(first + corner[a]);
                const int64_t kc = grid.Key(first + corner[c]);
                return std::make_pair(std::min(ka, kc), std::max(ka, kc));
              };
              const Eigen::Vector3d outward = out_mean - in_mean;
              if (n_in == 1 || n_out == 1) {
                const bool lone_in = n_in == 1;
                const int lone = lone_in ? in[0] : out[0];
                const auto& others = lone_in ? out : in;
                pieces[b].push_back(
                    {{key(lone, others[0]), key(lone, others[1]), key(lone, others[2])}, outward});
              } else {
                // A quad between in[0], in[1] and out[0], out[1], cut in two.
                const auto e00 = key(in[0], out[0]), e01 = key(in[0], out[1]);
                const auto e11 = key(in[1], out[1]), e10 = key(in[1], out[0]);
                pieces[b].push_back({{e00, e01, e11}, outward});
                pieces[b].push_back({{e00, e11, e10}, outward});
              }
            }
            for (int c = 0; c < 8; ++c) values[b][grid.Key(first + corner[c])] = v[c];
          }
    }
  });

  // One vertex per cut edge, on the field's zero; numbered in block order so the mesh is
  // the same for any thread count.
  std::unordered_map<std::pair<int64_t, int64_t>, int, EdgeKeyHash> vertex_of_edge;
  std::vector<std::pair<int64_t, int64_t>> edges;
  std::vector<std::pair<float, float>> edge_values;
  for (size_t b = 0; b < active.size(); ++b)
    for (const Piece& piece : pieces[b])
      for (const auto& e : piece.edges)
        if (vertex_of_edge.emplace(e, static_cast<int>(edges.size())).second) {
          edges.push_back(e);
          edge_values.emplace_back(values[b].at(e.first), values[b].at(e.second));
        }
  values.clear();
  TriangleMesh mesh;
  mesh.vertices.resize(edges.size());
  auto position_of = [&](int64_t key) {
    const int64_t x = key % grid.points.x();
    const int64_t y = (key / grid.points.x()) % grid.points.y();
    const int64_t z = key / (static_cast<int64_t>(grid.points.x()) * grid.points.y());
    return grid.Position(
        Eigen::Vector3i(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)));
  };
  ParallelFor(edges.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i)
      mesh.vertices[i] = ZeroOnEdge(field, position_of(edges[i].first), edge_values[i].first,
                                    position_of(edges[i].second), edge_values[i].second);
  });
  // Orientation from the edges' midpoints: through them each piece is a triangle parallel
  // to a face of its tetrahedron, or a parallelogram parallel to two of its edges, so its
  // normal is never degenerate and its side is exact (a moved vertex can make a sliver).
  auto midpoint = [&](int i) {
    return (0.5 * (position_of(edges[i].first) + position_of(edges[i].second))).eval();
  };
  for (const auto& block : pieces)
    for (const Piece& piece : block) {
      Eigen::Vector3i t(vertex_of_edge.at(piece.edges[0]), vertex_of_edge.at(piece.edges[1]),
                        vertex_of_edge.at(piece.edges[2]));
      const Eigen::Vector3d p0 = midpoint(t[0]);
      const Eigen::Vector3d normal = (midpoint(t[1]) - p0).cross(midpoint(t[2]) - p0);
      if (normal.dot(piece.outward) < 0) std::swap(t[1], t[2]);
      mesh.triangles.push_back(t);
    }
  return mesh;
}

}  // namespace mirrorscan::virtual_cabinet

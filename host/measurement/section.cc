#include "host/measurement/section.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <unordered_map>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

namespace mirrorscan::measurement {
namespace {

struct VertexKey {
  double x, y, z;
  bool operator==(const VertexKey&) const = default;
};
struct VertexKeyHash {
  size_t operator()(const VertexKey& k) const {
    const std::hash<double> h;
    return h(k.x) ^ (h(k.y) * 31) ^ (h(k.z) * 1000003);
  }
};

bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

double SegmentPointDistance(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                            const Eigen::Vector2d& p) {
  const Eigen::Vector2d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t = length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

struct Box2 {
  Eigen::Vector2d lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  Eigen::Vector2d hi{std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
  void Add(const Eigen::Vector2d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  bool Overlaps(const Box2& o, double margin) const {
    return lo.x() <= o.hi.x() + margin && o.lo.x() <= hi.x() + margin &&
           lo.y() <= o.hi.y() + margin && o.lo.y() <= hi.y() + margin;
  }
};

// Two closed loops belong to one part when one has a point inside the other.
bool LoopsTouch(const SectionLoop& a, const SectionLoop& b) {
  for (const Eigen::Vector2d& p : a.points) {
    if (InsidePolygon(b.points, p)) return true;
  }
  for (const Eigen::Vector2d& p : b.points) {
    if (InsidePolygon(a.points, p)) return true;
  }
  return false;
}

// Followed outline: the edges of each loop not inside another loop of the part.
double ContourLength(const std::vector<SectionLoop>& loops, const std::vector<int>& members) {
  double length = 0.0;
  for (int i : members) {
    const SectionLoop& loop = loops[i];
    if (!loop.closed) continue;
    for (size_t k = 0; k < loop.points.size(); ++k) {
      const Eigen::Vector2d& a = loop.points[k];
      const Eigen::Vector2d& b = loop.points[(k + 1) % loop.points.size()];
      const Eigen::Vector2d mid = 0.5 * (a + b);
      bool covered = false;
      for (int j : members) {
        if (j != i && loops[j].closed && InsidePolygon(loops[j].points, mid)) {
          covered = true;
          break;
        }
      }
      if (!covered) length += (b - a).norm();
    }
  }
  return length;
}

SectionPart MakePart(const std::vector<SectionLoop>& loops, std::vector<int> members) {
  SectionPart part;
  part.loops = std::move(members);
  std::vector<cv::Point2f> points;
  for (int i : part.loops) {
    part.has_hole |= !loops[i].closed;
    for (const Eigen::Vector2d& p : loops[i].points) points.emplace_back(p.x(), p.y());
  }
  std::vector<cv::Point2f> hull;
  if (points.size() >= 3) cv::convexHull(points, hull, /*clockwise=*/false);
  for (const cv::Point2f& p : hull) part.hull.emplace_back(p.x, p.y);
  // OpenCV's "counter-clockwise" is in image axes (y down); make it so in ours.
  double signed_area = 0.0;
  Eigen::Vector2d moment = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < part.hull.size(); ++k) {
    const Eigen::Vector2d& a = part.hull[k];
    const Eigen::Vector2d& b = part.hull[(k + 1) % part.hull.size()];
    const double cross = a.x() * b.y() - a.y() * b.x();
    signed_area += 0.5 * cross;
    moment += cross * (a + b) / 6.0;
    part.tape_mm += (b - a).norm();
  }
  if (signed_area < 0.0) std::reverse(part.hull.begin(), part.hull.end());
  part.area_mm2 = std::abs(signed_area);
  part.centroid = part.area_mm2 > 0.0 ? Eigen::Vector2d(moment / signed_area)
                  : part.hull.empty() ? Eigen::Vector2d::Zero()
                                      : part.hull.front();
  part.contour_mm = ContourLength(loops, part.loops);
  return part;
}

// Groups loops into parts: closed loops that overlap, and open chains near them.
std::vector<SectionPart> GroupParts(const std::vector<SectionLoop>& loops) {
  const int n = static_cast<int>(loops.size());
  std::vector<Box2> boxes(n);
  for (int i = 0; i < n; ++i) {
    for (const Eigen::Vector2d& p : loops[i].points) boxes[i].Add(p);
  }
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&parent](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const bool both_closed = loops[i].closed && loops[j].closed;
      // An open chain joins what lies within 20 mm of it: the hole's rim and its part.
      if (!boxes[i].Overlaps(boxes[j], both_closed ? 0.0 : 20.0)) continue;
      if (both_closed && !LoopsTouch(loops[i], loops[j])) continue;
      parent[find(i)] = find(j);
    }
  }
  std::map<int, std::vector<int>> groups;
  for (int i = 0; i < n; ++i) groups[find(i)].push_back(i);
  std::vector<SectionPart> parts;
  for (auto& [root, members] : groups) parts.push_back(MakePart(loops, std::move(members)));
  std::sort(parts.begin(), parts.end(),
            [](const SectionPart& a, const SectionPart& b) { return a.area_mm2 > b.area_mm2; });
  return parts;
}

}  // namespace

bool SectionPart::Contains(const Eigen::Vector2d& p) const {
  return hull.size() >= 3 && InsidePolygon(hull, p);
}

double SectionPart::DistanceTo(const SectionPart& other) const {
  for (const Eigen::Vector2d& p : other.hull) {
    if (Contains(p)) return 0.0;
  }
  for (const Eigen::Vector2d& p : hull) {
    if (other.Contains(p)) return 0.0;
  }
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    for (size_t j = 0; j < other.hull.size(); ++j) {
      best = std::min(
          {best, SegmentPointDistance(hull[i], hull[(i + 1) % hull.size()], other.hull[j]),
           SegmentPointDistance(other.hull[j], other.hull[(j + 1) % other.hull.size()], hull[i])});
    }
  }
  return best;
}

SurfaceMesh WeldVertices(const SurfaceMesh& mesh) {
  SurfaceMesh welded;
  std::unordered_map<VertexKey, int, VertexKeyHash> index;
  std::vector<int> remap(mesh.vertices.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    const auto [it, added] =
        index.emplace(VertexKey{v.x(), v.y(), v.z()}, static_cast<int>(welded.vertices.size()));
    if (added) welded.vertices.push_back(v);
    remap[i] = it->second;
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3i r(remap[t[0]], remap[t[1]], remap[t[2]]);
    if (r[0] != r[1] && r[1] != r[2] && r[0] != r[2]) welded.triangles.push_back(r);
  }
  return welded;
}

Slicer::Slicer(SurfaceMesh mesh) : mesh_(std::move(mesh)) {
  if (mesh_.vertices.empty()) return;
  double z_max = std::numeric_limits<double>::lowest();
  z_min_ = std::numeric_limits<double>::max();
  for (const Eigen::Vector3d& v : mesh_.vertices) {
    z_min_ = std::min(z_min_, v.z());
    z_max = std::max(z_max, v.z());
  }
  buckets_.resize(static_cast<size_t>((z_max - z_min_) / bucket_mm_) + 1);
  for (int i = 0; i < static_cast<int>(mesh_.triangles.size()); ++i) {
    const Eigen::Vector3i& t = mesh_.triangles[i];
    const double lo =
        std::min({mesh_.vertices[t[0]].z(), mesh_.vertices[t[1]].z(), mesh_.vertices[t[2]].z()});
    const double hi =
        std::max({mesh_.vertices[t[0]].z(), mesh_.vertices[t[1]].z(), mesh_.vertices[t[2]].z()});
    const size_t first = static_cast<size_t>((lo - z_min_) / bucket_mm_);
    const size_t last =
        std::min(buckets_.size() - 1, static_cast<size_t>((hi - z_min_) / bucket_mm_));
    for (size_t b = first; b <= last; ++b) buckets_[b].push_back(i);
  }
}

Section Slicer::AtHeight(double z) const {
  static const std::vector<int> kNone;
  const double b = (z - z_min_) / bucket_mm_;
  const std::vector<int>& triangles = (b < 0.0 || b >= static_cast<double>(buckets_.size()))
                                          ? kNone
                                          : buckets_[static_cast<size_t>(b)];
  return Cut(triangles, Eigen::Vector3d(0, 0, z), Eigen::Vector3d::UnitZ(),
             Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
}

Section Slicer::ByPlane(const Eigen::Vector3d& origin, const Eigen::Vector3d& normal) const {
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  std::vector<int> all(mesh_.triangles.size());
  std::iota(all.begin(), all.end(), 0);
  return Cut(all, origin, n, e1, e2);
}

Section Slicer::Cut(const std::vector<int>& triangles, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& normal, const Eigen::Vector3d& e1,
                    const Eigen::Vector3d& e2) const {
  Section section;
  section.origin = origin;
  section.e1 = e1;
  section.e2 = e2;
  auto distance = [&](int v) { return (mesh_.vertices[v] - origin).dot(normal); };
  auto edge_key = [](int a, int b) {
    return (static_cast<uint64_t>(std::min(a, b)) << 32) | static_cast<uint32_t>(std::max(a, b));
  };
  // Each crossed triangle gives a segment between two crossed edges; a crossed edge is
  // shared by (at most) two triangles, so segments chain through edges.
  std::vector<std::pair<uint64_t, uint64_t>> segments;
  std::unordered_map<uint64_t, Eigen::Vector2d> points;
  std::unordered_map<uint64_t, std::vector<int>> edge_segments;
  for (int i : triangles) {
    const Eigen::Vector3i& t = mesh_.triangles[i];
    const double d[3] = {distance(t[0]), distance(t[1]), distance(t[2])};
    uint64_t keys[2];
    int found = 0;
    for (int k = 0; k < 3; ++k) {
      const int a = k, b = (k + 1) % 3;
      if ((d[a] >= 0.0) == (d[b] >= 0.0)) continue;
      const uint64_t key = edge_key(t[a], t[b]);
      if (!points.count(key)) {
        const double s = d[a] / (d[a] - d[b]);
        const Eigen::Vector3d p =
            mesh_.vertices[t[a]] + s * (mesh_.vertices[t[b]] - mesh_.vertices[t[a]]) - origin;
        points[key] = Eigen::Vector2d(p.dot(e1), p.dot(e2));
      }
      if (found < 2) keys[found++] = key;
    }
    if (found != 2) continue;
    edge_segments[keys[0]].push_back(static_cast<int>(segments.size()));
    edge_segments[keys[1]].push_back(static_cast<int>(segments.size()));
    segments.emplace_back(keys[0], keys[1]);
  }
  std::vector<bool> used(segments.size(), false);
  // The segment on edge `key` other than `from`, unused; -1 at a border.
  auto next = [&](uint64_t key, int from) {
    for (int s : edge_segments[key]) {
      if (s != from && !used[s]) return s;
    }
    return -1;
  };
  auto other_end = [&](int s, uint64_t key) {
    return segments[s].first == key ? segments[s].second : segments[s].first;
  };
  for (int start = 0; start < static_cast<int>(segments.size()); ++start) {
    if (used[start]) continue;
    used[start] = true;
    std::vector<uint64_t> chain = {segments[start].first, segments[start].second};
    bool closed = false;
    for (int s = start;;) {
      const int n = next(chain.back(), s);
      if (n < 0) break;
      used[n] = true;
      const uint64_t end = other_end(n, chain.back());
      s = n;
      if (end == chain.front()) {
        closed = true;
        break;
      }
      chain.push_back(end);
    }
    if (!closed) {  // walk back from the start too, so the chain is whole
      std::vector<uint64_t> back;
      for (int s = start;;) {
        const uint64_t from = back.empty() ? chain.front() : back.back();
        const int n = next(from, s);
        if (n < 0) break;
        used[n] = true;
        back.push_back(other_end(n, from));
        s = n;
      }
      chain.insert(chain.begin(), back.rbegin(), back.rend());
    }
    SectionLoop loop;
    loop.closed = closed && chain.size() >= 3;
    for (uint64_t key : chain) loop.points.push_back(points[key]);
    section.loops.push_back(std::move(loop));
  }
  section.parts = GroupParts(section.loops);
  return section;
}

std::vector<LineCrossing> CrossLine(const SurfaceMesh& mesh, const Eigen::Vector3d& origin,
                                    const Eigen::Vector3d& direction) {
  std::vector<LineCrossing> crossings;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[t[0]];
    const Eigen::Vector3d e1 = mesh.vertices[t[1]] - a, e2 = mesh.vertices[t[2]] - a;
    // Moller-Trumbore, for the whole line (t of either sign).
    const Eigen::Vector3d p = direction.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-12) continue;
    const Eigen::Vector3d s = origin - a;
    const double u = s.dot(p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = direction.dot(q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double along = e2.dot(q) / det;
    crossings.push_back({along, e1.cross(e2).dot(direction) > 0.0 ? +1 : -1});
  }
  std::sort(crossings.begin(), crossings.end(),
            [](const LineCrossing& x, const LineCrossing& y) { return x.t < y.t; });
  // A line through a shared edge hits both triangles: one crossing.
  std::vector<LineCrossing> unique;
  for (const LineCrossing& c : crossings) {
    if (!unique.empty() && unique.back().sign == c.sign && c.t - unique.back().t < 1e-9) continue;
    unique.push_back(c);
  }
  return unique;
}

}  // namespace mirrorscan::measurement

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

// Two loops belong to one part when one has a point inside the other (a closed one).
bool LoopsTouch(const SectionLoop& a, const SectionLoop& b) {
  for (const Eigen::Vector2d& p : a.points) {
    if (b.closed && InsidePolygon(b.points, p)) return true;
  }
  for (const Eigen::Vector2d& p : b.points) {
    if (a.closed && InsidePolygon(a.points, p)) return true;
  }
  return false;
}

// Some point of `a` within `distance` of some point of `b` (the points lie a few mm
// apart). Not the boxes: two legs side by side at 45° have overlapping boxes while their
// outlines are far apart.
bool ChainsWithin(const SectionLoop& a, const SectionLoop& b, double distance) {
  const double d2 = distance * distance;
  for (const Eigen::Vector2d& p : a.points) {
    for (const Eigen::Vector2d& q : b.points) {
      if ((p - q).squaredNorm() <= d2) return true;
    }
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

double ChainLength(const std::vector<Eigen::Vector2d>& points) {
  double length = 0.0;
  for (size_t k = 1; k < points.size(); ++k) length += (points[k] - points[k - 1]).norm();
  return length;
}

// The direction in which an open chain leaves its front (or back) end: the directions
// of its last two stretches of kEndStretchMm, the turn between them carried on to the end
// (exact on a circle; the chord of the last stretch alone would point outward of the
// curve by half that stretch's turn, and a ragged border's last segment alone is noise).
constexpr double kEndStretchMm = 8.0;
Eigen::Vector2d EndDirection(const std::vector<Eigen::Vector2d>& points, bool back,
                             double* turn_out) {
  const int n = static_cast<int>(points.size());
  auto at = [&](int k) -> const Eigen::Vector2d& { return back ? points[n - 1 - k] : points[k]; };
  // The first index at least `length` along the chain from the end (or the last one).
  auto along = [&](double length) {
    int k = 0;
    for (double walked = 0.0; k + 1 < n && walked < length; ++k)
      walked += (at(k + 1) - at(k)).norm();
    return k;
  };
  const int k1 = along(kEndStretchMm), k2 = along(2.0 * kEndStretchMm);
  const Eigen::Vector2d near = at(0) - at(k1), far = at(k1) - at(k2);
  *turn_out = 0.0;
  if (near.norm() < 1e-9) return Eigen::Vector2d::Zero();
  if (far.norm() < 1e-9 || k2 == k1) return near.normalized();
  const double turn = std::atan2(far.x() * near.y() - far.y() * near.x(), far.dot(near));
  *turn_out = turn;
  return Eigen::Rotation2Dd(0.5 * turn) * near.normalized();
}

// An end of an open chain: where it stops, the direction in which it leaves, and how it
// turns on the way there (radians per kEndStretchMm, counter-clockwise positive).
struct ChainEnd {
  int loop;
  Eigen::Vector2d point, out;
  double turn = 0.0;
};

// Ends of open chains joined across the holes between them: each end to at most one
// other (a chain's two ends may meet each other), chosen so that the outline continues
// smoothly: both ends must point towards each other, the bridge must bend the way both
// chains bend (two limbs' open sides facing each other point towards each other too, but
// joining them would bend against both), and pairs are taken cheapest first, by the gap
// times how far each end turns away from it. Returns each end's partner or -1.
constexpr double kMaxJoinMm = 400.0;    // measurement decides what it accepts
constexpr double kMinTowardsCos = 0.2;  // an end turned further from the gap does not continue
constexpr double kMinTurn = 0.05;       // a chain bending less than this is taken as straight
std::vector<int> JoinEnds(const std::vector<ChainEnd>& ends) {
  std::vector<std::pair<double, std::pair<int, int>>> pairs;
  for (int a = 0; a < static_cast<int>(ends.size()); ++a) {
    for (int b = a + 1; b < static_cast<int>(ends.size()); ++b) {
      const Eigen::Vector2d d = ends[b].point - ends[a].point;
      const double gap = d.norm();
      if (gap > kMaxJoinMm) continue;
      double cost = gap;
      if (gap >= 1.0) {
        const double cos_a = ends[a].out.dot(d) / gap, cos_b = -ends[b].out.dot(d) / gap;
        if (cos_a < kMinTowardsCos || cos_b < kMinTowardsCos) continue;
        // Leaving a, entering b (b's chain then runs against its own leaving direction).
        const Eigen::Vector2d in_b = -ends[b].out;
        const double bend = ends[a].out.x() * in_b.y() - ends[a].out.y() * in_b.x();
        if ((std::abs(ends[a].turn) > kMinTurn && bend * ends[a].turn < 0.0) ||
            (std::abs(ends[b].turn) > kMinTurn && bend * -ends[b].turn < 0.0)) {
          continue;
        }
        cost *= 3.0 - cos_a - cos_b;
      }
      pairs.push_back({cost, {a, b}});
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<int> partner(ends.size(), -1);
  for (const auto& [cost, ab] : pairs) {
    if (partner[ab.first] < 0 && partner[ab.second] < 0) {
      partner[ab.first] = ab.second;
      partner[ab.second] = ab.first;
    }
  }
  return partner;
}

// A bridge from end a to end b: a cubic Hermite curve that leaves a and enters b along
// the chains' own directions, so an arc of a smooth outline is followed closely (a quarter
// circle to 0.03 % of its radius) where a straight chord would cut the corner. Appends its
// inner points; returns its length.
double Bridge(const ChainEnd& a, const ChainEnd& b, std::vector<Eigen::Vector2d>* points) {
  const double gap = (b.point - a.point).norm();
  if (gap < 1.0) return gap;  // a chord is as good
  // Tangents of gap / cos²(θ/4), θ the turn from leaving a to entering b: the cubic that
  // best follows a circular arc of that turn.
  const double turn = std::acos(std::clamp(a.out.dot(-b.out), -1.0, 1.0));
  const double c = std::cos(turn / 4.0);
  const Eigen::Vector2d m0 = gap / (c * c) * a.out, m1 = -gap / (c * c) * b.out;
  constexpr int kSamples = 16;
  Eigen::Vector2d previous = a.point;
  double length = 0.0;
  for (int k = 1; k < kSamples; ++k) {
    const double t = static_cast<double>(k) / kSamples, t2 = t * t, t3 = t2 * t;
    const Eigen::Vector2d p = (2 * t3 - 3 * t2 + 1) * a.point + (t3 - 2 * t2 + t) * m0 +
                              (-2 * t3 + 3 * t2) * b.point + (t3 - t2) * m1;
    points->push_back(p);
    length += (p - previous).norm();
    previous = p;
  }
  return length + (b.point - previous).norm();
}

// `ends` and `partner` of the whole section; the part's open chains are bridged when
// every end of theirs has a partner.
SectionPart MakePart(const std::vector<SectionLoop>& loops, std::vector<int> members,
                     const std::vector<ChainEnd>& ends, const std::vector<int>& partner) {
  SectionPart part;
  part.loops = std::move(members);
  std::vector<cv::Point2f> points;
  double open_length = 0.0;
  for (int i : part.loops) {
    if (!loops[i].closed) {
      part.has_hole = true;
      open_length += ChainLength(loops[i].points);
    }
    for (const Eigen::Vector2d& p : loops[i].points) points.emplace_back(p.x(), p.y());
  }
  if (part.has_hole) {
    std::vector<Eigen::Vector2d> bridge_points;
    part.bridged = true;
    for (int e = 0; e < static_cast<int>(ends.size()) && part.bridged; ++e) {
      if (std::find(part.loops.begin(), part.loops.end(), ends[e].loop) == part.loops.end()) {
        continue;
      }
      if (partner[e] < 0) {
        part.bridged = false;
      } else if (partner[e] > e) {
        const double gap = (ends[partner[e]].point - ends[e].point).norm();
        part.largest_bridge_mm = std::max(part.largest_bridge_mm, gap);
        part.bridged_mm += Bridge(ends[e], ends[partner[e]], &bridge_points);
      }
    }
    if (part.bridged) {
      for (const Eigen::Vector2d& p : bridge_points) points.emplace_back(p.x(), p.y());
    } else {
      part.bridged_mm = part.largest_bridge_mm = 0.0;
    }
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
  if (part.bridged) part.contour_mm += open_length + part.bridged_mm;
  return part;
}

// Groups loops into parts: closed loops that overlap, open chains joined end to end
// across their holes (JoinEnds), and open chains lying in a closed loop; without
// `join_holes`, open chains with whatever lies within 20 mm of them.
std::vector<SectionPart> GroupParts(const std::vector<SectionLoop>& loops, bool join_holes) {
  const int n = static_cast<int>(loops.size());
  std::vector<Box2> boxes(n);
  for (int i = 0; i < n; ++i) {
    for (const Eigen::Vector2d& p : loops[i].points) boxes[i].Add(p);
  }
  std::vector<ChainEnd> ends;
  for (int i = 0; i < n; ++i) {
    if (loops[i].closed || loops[i].points.size() < 2) continue;
    for (bool back : {false, true}) {
      ChainEnd end{i, back ? loops[i].points.back() : loops[i].points.front(),
                   Eigen::Vector2d::Zero()};
      end.out = EndDirection(loops[i].points, back, &end.turn);
      ends.push_back(end);
    }
  }
  const std::vector<int> partner = join_holes ? JoinEnds(ends) : std::vector<int>(ends.size(), -1);
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&parent](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (int e = 0; e < static_cast<int>(ends.size()); ++e) {
    if (partner[e] >= 0) parent[find(ends[e].loop)] = find(ends[partner[e]].loop);
  }
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const bool both_closed = loops[i].closed && loops[j].closed;
      if (!join_holes && !both_closed) {
        if (boxes[i].Overlaps(boxes[j], 20.0) && ChainsWithin(loops[i], loops[j], 20.0)) {
          parent[find(i)] = find(j);
        }
        continue;
      }
      if (!loops[i].closed && !loops[j].closed) continue;
      if (!boxes[i].Overlaps(boxes[j], 0.0) || !LoopsTouch(loops[i], loops[j])) continue;
      parent[find(i)] = find(j);
    }
  }
  std::map<int, std::vector<int>> groups;
  for (int i = 0; i < n; ++i) groups[find(i)].push_back(i);
  std::vector<SectionPart> parts;
  for (auto& [root, members] : groups) {
    parts.push_back(MakePart(loops, std::move(members), ends, partner));
  }
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

TriangleMesh WeldVertices(const TriangleMesh& mesh) {
  TriangleMesh welded;
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

Slicer::Slicer(TriangleMesh mesh) : mesh_(std::move(mesh)) {
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

Section Slicer::AtHeight(double z, bool join_holes) const {
  static const std::vector<int> kNone;
  const double b = (z - z_min_) / bucket_mm_;
  const std::vector<int>& triangles = (b < 0.0 || b >= static_cast<double>(buckets_.size()))
                                          ? kNone
                                          : buckets_[static_cast<size_t>(b)];
  return Cut(triangles, Eigen::Vector3d(0, 0, z), Eigen::Vector3d::UnitZ(),
             Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), join_holes);
}

Section Slicer::ByPlane(const Eigen::Vector3d& origin, const Eigen::Vector3d& normal) const {
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  std::vector<int> all(mesh_.triangles.size());
  std::iota(all.begin(), all.end(), 0);
  return Cut(all, origin, n, e1, e2, /*join_holes=*/true);
}

Section Slicer::Cut(const std::vector<int>& triangles, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& normal, const Eigen::Vector3d& e1,
                    const Eigen::Vector3d& e2, bool join_holes) const {
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
  section.parts = GroupParts(section.loops, join_holes);
  return section;
}

std::vector<LineCrossing> CrossLine(const TriangleMesh& mesh, const Eigen::Vector3d& origin,
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

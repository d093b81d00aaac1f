#include "boards/virtual/body_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>

namespace mirrorscan::virtual_cabinet {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// Two unit vectors spanning the plane with this normal.
std::pair<Vector3d, Vector3d> PlaneBasis(const Vector3d& normal) {
  const Vector3d n = normal.normalized();
  const Vector3d e1 = n.unitOrthogonal();
  return {e1, n.cross(e1)};
}

std::vector<Vector2d> InPlane(const std::vector<Vector3d>& loop, const Vector3d& origin,
                              const Vector3d& normal) {
  const auto [e1, e2] = PlaneBasis(normal);
  std::vector<Vector2d> points;
  points.reserve(loop.size());
  for (const Vector3d& p : loop) points.emplace_back((p - origin).dot(e1), (p - origin).dot(e2));
  return points;
}

bool Contains(const std::vector<Vector2d>& polygon, const Vector2d& point) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vector2d& a = polygon[i];
    const Vector2d& b = polygon[j];
    if ((a.y() > point.y()) != (b.y() > point.y()) &&
        point.x() < (b.x() - a.x()) * (point.y() - a.y()) / (b.y() - a.y()) + a.x())
      inside = !inside;
  }
  return inside;
}

double HullPerimeter2d(std::vector<Vector2d> points) {
  std::sort(points.begin(), points.end(), [](const Vector2d& a, const Vector2d& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  });
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) return 0;
  auto turn = [](const Vector2d& o, const Vector2d& a, const Vector2d& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<Vector2d> lower, upper;
  for (const Vector2d& p : points) {
    while (lower.size() >= 2 && turn(lower[lower.size() - 2], lower.back(), p) <= 0)
      lower.pop_back();
    lower.push_back(p);
  }
  for (auto it = points.rbegin(); it != points.rend(); ++it) {
    while (upper.size() >= 2 && turn(upper[upper.size() - 2], upper.back(), *it) <= 0)
      upper.pop_back();
    upper.push_back(*it);
  }
  double length = 0;
  for (size_t i = 0; i + 1 < lower.size(); ++i) length += (lower[i + 1] - lower[i]).norm();
  for (size_t i = 0; i + 1 < upper.size(); ++i) length += (upper[i + 1] - upper[i]).norm();
  return length;
}

// The loop around `center` (containing it), or nullopt.
std::optional<std::vector<Vector3d>> LoopAround(const TriangleMesh& mesh, const Vector3d& center,
                                                const Vector3d& normal) {
  for (auto& loop : CutLoops(mesh, center, normal)) {
    if (Contains(InPlane(loop, center, normal), Vector2d::Zero())) return loop;
  }
  return std::nullopt;
}

bool LoopContains(const std::vector<Vector3d>& loop, const Vector3d& origin, const Vector3d& normal,
                  const Vector3d& point) {
  const auto [e1, e2] = PlaneBasis(normal);
  return Contains(InPlane(loop, origin, normal),
                  Vector2d((point - origin).dot(e1), (point - origin).dot(e2)));
}

double PolylineLength(const std::vector<Vector3d>& line) {
  double length = 0;
  for (size_t i = 0; i + 1 < line.size(); ++i) length += (line[i + 1] - line[i]).norm();
  return length;
}

// Upward ray from `from`: the height of the first triangle it meets (Moller-Trumbore).
std::optional<double> FirstHitUp(const TriangleMesh& mesh, const Vector3d& from) {
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Vector3d& a = mesh.vertices[t[0]];
    const Vector3d& b = mesh.vertices[t[1]];
    const Vector3d& c = mesh.vertices[t[2]];
    // In xy the point must lie in the triangle's projection.
    const Vector2d p = from.head<2>(), pa = a.head<2>(), pb = b.head<2>(), pc = c.head<2>();
    auto cross = [](const Vector2d& u, const Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); };
    const double d = cross(pb - pa, pc - pa);
    if (std::abs(d) < 1e-12) continue;
    const double u = cross(p - pa, pc - pa) / d, v = cross(pb - pa, p - pa) / d;
    if (u < 0 || v < 0 || u + v > 1) continue;
    const double z = a.z() + u * (b.z() - a.z()) + v * (c.z() - a.z());
    if (z > from.z() && z < best) best = z;
  }
  if (!std::isfinite(best)) return std::nullopt;
  return best;
}

nlohmann::json Value(double mm, const char* definition) {
  return {{"value_mm", mm}, {"definition", definition}};
}
nlohmann::json Withheld(const char* definition, const std::string& why) {
  return {{"value_mm", nullptr}, {"definition", definition}, {"why", why}};
}
// Where a girth is taken: the plane's point (inside the loop) and normal, world frame.
nlohmann::json Section(const Vector3d& point, const Vector3d& normal) {
  return {{"point", {point.x(), point.y(), point.z()}},
          {"normal", {normal.x(), normal.y(), normal.z()}}};
}

}  // namespace

std::vector<std::vector<Vector3d>> CutLoops(const TriangleMesh& mesh, const Vector3d& plane_point,
                                            const Vector3d& plane_normal) {
  const Vector3d n = plane_normal.normalized();
  std::vector<double> side(mesh.vertices.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    side[i] = (mesh.vertices[i] - plane_point).dot(n);
    if (side[i] == 0) side[i] = 1e-12;  // on the plane counts as above
  }
  using Edge = std::pair<int, int>;
  auto edge = [](int a, int b) { return a < b ? Edge{a, b} : Edge{b, a}; };
  // Each cut triangle gives a segment from one cut edge to another; on a closed manifold
  // mesh every cut edge has two such segments, so the segments chain into loops.
  std::map<Edge, std::vector<Edge>> next;
  std::map<Edge, Vector3d> point;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    std::vector<Edge> cut;
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if ((side[a] < 0) == (side[b] < 0)) continue;
      const Edge e = edge(a, b);
      cut.push_back(e);
      if (!point.count(e)) {
        const double s = side[a] / (side[a] - side[b]);
        point[e] = mesh.vertices[a] + s * (mesh.vertices[b] - mesh.vertices[a]);
      }
    }
    if (cut.size() != 2) continue;
    next[cut[0]].push_back(cut[1]);
    next[cut[1]].push_back(cut[0]);
  }
  std::vector<std::vector<Vector3d>> loops;
  std::map<Edge, bool> used;
  for (const auto& [start, links] : next) {
    if (used[start]) continue;
    std::vector<Vector3d> loop;
    Edge previous{-1, -1}, current = start;
    while (!used[current]) {
      used[current] = true;
      loop.push_back(point[current]);
      const auto& options = next[current];
      Edge following = options[0] == previous && options.size() > 1 ? options[1] : options[0];
      previous = current;
      current = following;
    }
    if (loop.size() >= 3) loops.push_back(std::move(loop));
  }
  return loops;
}

double TapeLength(const std::vector<Vector3d>& loop, const Vector3d& normal) {
  return HullPerimeter2d(InPlane(loop, loop.front(), normal));
}

nlohmann::json BodyMeasurementTruth(const TriangleMesh& mesh, const BodyLandmarks& marks) {
  nlohmann::json out;
  const Vector3d up = marks.up;
  auto at_height = [&](double z) { return marks.world_from_upright * Vector3d(0, 0, z); };
  // Where the left arm's axis (shoulder to elbow, then on to the wrist) crosses the
  // horizontal plane through `point`: a torso section holding it has merged with the arm.
  auto arm_at = [&](const Vector3d& point) {
    const Vector3d& a = marks.shoulder_joint[0];
    const Vector3d& b =
        point.z() > marks.elbow_joint[0].z() ? marks.elbow_joint[0] : marks.wrist_joint[0];
    const Vector3d& from = point.z() > marks.elbow_joint[0].z() ? a : marks.elbow_joint[0];
    return Vector3d(from + (point.z() - from.z()) / (b.z() - from.z()) * (b - from));
  };
  // A girth: the tape around the loop holding `center` in the plane through it with that
  // normal; withheld when that loop also holds `apart` (merged with another part).
  auto girth = [&](const char* key, const char* definition, const Vector3d& center,
                   const Vector3d& normal, std::optional<Vector3d> apart = std::nullopt) {
    const auto loop = LoopAround(mesh, center, normal);
    if (!loop) {
      out[key] = Withheld(definition, "no loop of the surface around the station");
    } else if (apart && LoopContains(*loop, center, normal, *apart)) {
      out[key] = Withheld(definition, "the section merges with another body part");
    } else {
      out[key] = Value(TapeLength(*loop, normal), definition);
      out[key]["section"] = Section(center, normal);
    }
  };

  double top = -std::numeric_limits<double>::infinity();
  for (const Vector3d& v : mesh.vertices) top = std::max(top, v.z());
  out["stature"] =
      Value(top, "vertical distance from the floor to the vertex (highest point of the head)");
  out["cervical_height"] =
      Value(marks.cervicale.z(), "vertical distance from the floor to the cervicale (C7)");
  out["waist_height"] =
      Value(at_height(marks.waist_z).z(), "vertical distance from the floor to the waist level");
  {
    const auto hit = FirstHitUp(mesh, Vector3d(marks.crotch.x(), marks.crotch.y(), 1.0));
    const char* def = "vertical distance from the floor to the crotch (inside leg length)";
    out["crotch_height"] = hit ? Value(*hit, def) : Withheld(def, "no surface above the floor");
  }
  girth("neck_girth", "girth of the neck just below the Adam's apple, perpendicular to its axis",
        at_height(marks.neck_z), up);
  girth("chest_girth",
        "horizontal girth at the bust points (women) or over the chest's fullest part (men), "
        "under the armpits, arms away",
        at_height(marks.chest_z), up, arm_at(at_height(marks.chest_z)));
  girth("underbust_girth", "horizontal girth just below the breasts", at_height(marks.underbust_z),
        up, arm_at(at_height(marks.underbust_z)));
  girth("waist_girth",
        "horizontal girth at the natural waist, between the lowest rib and the iliac crest",
        at_height(marks.waist_z), up, arm_at(at_height(marks.waist_z)));
  girth("hip_girth", "horizontal girth at the greatest protrusion of the buttocks",
        at_height(marks.hip_z), up, arm_at(at_height(marks.hip_z)));
  auto on_leg = [&](int side, double z) {
    // The hip-knee or knee-ankle line at that height.
    const Vector3d& hip = marks.hip_joint[side];
    const Vector3d& knee = marks.knee_joint[side];
    const Vector3d& ankle = marks.ankle_joint[side];
    const Vector3d world = at_height(z);
    const Vector3d& a = world.z() > knee.z() ? hip : knee;
    const Vector3d& b = world.z() > knee.z() ? knee : ankle;
    const double t = (world.z() - a.z()) / (b.z() - a.z());
    return Vector3d(a + t * (b - a));
  };
  const Vector3d& vertical = up;  // the legs lean with the body
  girth("thigh_girth",
        "horizontal girth of the thigh at its highest part, just below the gluteal fold",
        on_leg(0, marks.thigh_z), vertical, on_leg(1, marks.thigh_z));
  girth("knee_girth", "horizontal girth over the middle of the kneecap", marks.knee_joint[0],
        vertical);
  {
    // Calf: the greatest horizontal girth between knee and ankle; ankle: the least, above
    // the malleoli.
    const double z_knee = marks.knee_joint[0].z(), z_ankle = marks.ankle_joint[0].z();
    double calf = 0, ankle = std::numeric_limits<double>::infinity();
    Vector3d calf_at = marks.knee_joint[0], ankle_at = marks.ankle_joint[0];
    for (double z = z_ankle + 0.3 * (z_knee - z_ankle); z < z_knee - 0.12 * (z_knee - z_ankle);
         z += 2) {
      const Vector3d c = marks.knee_joint[0] + (z - z_knee) / (z_ankle - z_knee) *
                                                   (marks.ankle_joint[0] - marks.knee_joint[0]);
      if (const auto loop = LoopAround(mesh, c, vertical)) {
        const double length = TapeLength(*loop, vertical);
        if (length > calf) calf = length, calf_at = c;
      }
    }
    for (double z = z_ankle + 0.25 * (z_knee - z_ankle); z > z_ankle + 0.06 * (z_knee - z_ankle);
         z -= 2) {
      const Vector3d c = marks.knee_joint[0] + (z - z_knee) / (z_ankle - z_knee) *
                                                   (marks.ankle_joint[0] - marks.knee_joint[0]);
      if (const auto loop = LoopAround(mesh, c, vertical)) {
        const double length = TapeLength(*loop, vertical);
        if (length < ankle) ankle = length, ankle_at = c;
      }
    }
    out["calf_girth"] = Value(calf, "greatest horizontal girth of the calf");
    out["ankle_girth"] = Value(ankle, "least horizontal girth of the leg above the malleoli");
    out["calf_girth"]["section"] = Section(calf_at, vertical);
    out["ankle_girth"]["section"] = Section(ankle_at, vertical);
  }
  {
    const Vector3d axis = (marks.elbow_joint[0] - marks.shoulder_joint[0]).normalized();
    const double t = 0.5 * ((marks.acromion[0] - marks.shoulder_joint[0]).dot(axis) +
                            (marks.elbow[0] - marks.shoulder_joint[0]).dot(axis));
    // Withheld when the arm's section holds the trunk's axis too (arms against the body):
    // the trunk's centre at that height, moved into the section's plane.
    const Vector3d center = marks.shoulder_joint[0] + t * axis;
    const Vector3d trunk = at_height((marks.world_from_upright.inverse() * center).z());
    girth("upper_arm_girth",
          "girth of the upper arm perpendicular to its axis, midway between acromion and olecranon",
          center, axis, Vector3d(trunk - (trunk - center).dot(axis) * axis));
    const Vector3d fore = (marks.wrist_joint[0] - marks.elbow_joint[0]).normalized();
    girth("wrist_girth", "girth of the wrist over the ulnar styloid, perpendicular to the forearm",
          marks.wrist_joint[0], fore);
  }
  {
    const Vector3d d = marks.acromion[0] - marks.acromion[1];
    out["shoulder_breadth"] = Value((d - d.dot(up) * up).norm(),
                                    "biacromial breadth: horizontal distance between the acromia");
  }
  {
    // Back width: the tape over the back of the torso's section at the armpits' folds,
    // between its leftmost and rightmost points.
    const char* def =
        "distance across the back between the posterior armpit folds, over the surface";
    const Vector3d center = at_height(marks.back_width_z);
    const auto loop = LoopAround(mesh, center, up);
    if (!loop || LoopContains(*loop, center, up, arm_at(center))) {
      out["back_width"] = Withheld(def, "the section at the armpits merges with the arms");
    } else {
      // The posterior armpit folds lie a quarter of the section's half depth behind its
      // middle: the back is the loop's run behind that line, tape-bridged.
      double front = std::numeric_limits<double>::infinity(), rear = -front;
      for (const Vector3d& p : *loop) {
        front = std::min(front, -p.dot(marks.forward));
        rear = std::max(rear, -p.dot(marks.forward));
      }
      const double fold = 0.5 * (front + rear) + 0.25 * 0.5 * (rear - front);
      // Start the walk at the loop's front-most point so the back run is contiguous.
      size_t start = 0;
      for (size_t i = 0; i < loop->size(); ++i)
        if (-(*loop)[i].dot(marks.forward) < -(*loop)[start].dot(marks.forward)) start = i;
      std::vector<Vector3d> back;
      for (size_t k = 0; k < loop->size(); ++k) {
        const Vector3d& p = (*loop)[(start + k) % loop->size()];
        if (-p.dot(marks.forward) > fold) back.push_back(p);
      }
      if (back.size() < 3) {
        out["back_width"] = Withheld(def, "no back in the section");
      } else {
        out["back_width"] = Value(TapeLength(back, up) - (back.front() - back.back()).norm(), def);
      }
    }
  }
  {
    // Shoulder length: side neck point to acromion over the shoulder, in the plane through
    // both that holds the vertical.
    const char* def = "distance from the side neck point to the acromion over the shoulder";
    const Vector3d along = marks.acromion[0] - marks.side_neck[0];
    const Vector3d normal = along.cross(up).normalized();
    std::optional<double> length;
    for (const auto& loop : CutLoops(mesh, marks.side_neck[0], normal)) {
      auto nearest = [&](const Vector3d& p) {
        size_t best = 0;
        for (size_t i = 0; i < loop.size(); ++i)
          if ((loop[i] - p).squaredNorm() < (loop[best] - p).squaredNorm()) best = i;
        return best;
      };
      const size_t a = nearest(marks.side_neck[0]), b = nearest(marks.acromion[0]);
      if ((loop[a] - marks.side_neck[0]).norm() > 3 || (loop[b] - marks.acromion[0]).norm() > 3)
        continue;
      std::vector<Vector3d> one, other;
      for (size_t i = a;; i = (i + 1) % loop.size()) {
        one.push_back(loop[i]);
        if (i == b) break;
      }
      for (size_t i = b;; i = (i + 1) % loop.size()) {
        other.push_back(loop[i]);
        if (i == a) break;
      }
      length = std::min(PolylineLength(one), PolylineLength(other));
    }
    out["shoulder_length"] =
        length ? Value(*length, def) : Withheld(def, "no section through both points");
  }
  out["arm_length"] =
      Value((marks.elbow[0] - marks.acromion[0]).norm() + (marks.wrist[0] - marks.elbow[0]).norm(),
            "acromion to olecranon to ulnar styloid (shoulder-elbow-wrist)");
  {
    // Back neck to waist: from the cervicale down the back's midline to the waist level,
    // along the surface in the body's midsagittal plane.
    const char* def = "from the cervicale along the spine's surface to the waist level";
    const Vector3d waist = at_height(marks.waist_z);
    std::optional<double> length;
    for (const auto& loop : CutLoops(mesh, marks.cervicale, marks.left)) {
      size_t start = 0;
      for (size_t i = 0; i < loop.size(); ++i)
        if ((loop[i] - marks.cervicale).squaredNorm() <
            (loop[start] - marks.cervicale).squaredNorm())
          start = i;
      if ((loop[start] - marks.cervicale).norm() > 3) continue;
      // Walk from the cervicale in the direction that goes down the back.
      const size_t n = loop.size();
      const int step = (loop[(start + 5) % n] - loop[start]).dot(up) < 0 ? 1 : -1;
      double sum = 0;
      for (size_t k = 0, i = start; k < n; ++k) {
        const size_t j = (i + n + step) % n;
        if ((loop[j] - waist).dot(up) <= 0) {
          const double above = (loop[i] - waist).dot(up), below = (loop[j] - waist).dot(up);
          sum += (loop[j] - loop[i]).norm() * above / (above - below);
          length = sum;
          break;
        }
        sum += (loop[j] - loop[i]).norm();
        i = j;
      }
    }
    out["back_neck_to_waist"] = length ? Value(*length, def) : Withheld(def, "no midline section");
  }
  return out;
}

}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/subjects.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "common/mesh/mesh_io.h"

namespace mirrorscan::virtual_cabinet {
namespace {

constexpr double kPi = std::numbers::pi;
double Radians(double degrees) { return degrees * kPi / 180.0; }

nlohmann::json ToJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
nlohmann::json ToJson(const Eigen::Vector2d& v) { return {v.x(), v.y()}; }

using Ring = std::vector<Eigen::Vector3d>;

// A closed surface through `rings` (equal sizes, ordered along an axis u, each
// counter-clockwise about u), closed by fans to `first_cap` and `last_cap`. The winding
// makes every normal point out.
TriangleMesh Loft(const std::vector<Ring>& rings, const Eigen::Vector3d& first_cap,
                  const Eigen::Vector3d& last_cap) {
  const int n = static_cast<int>(rings.front().size());
  const int ring_count = static_cast<int>(rings.size());
  TriangleMesh mesh;
  mesh.vertices.reserve(n * ring_count + 2);
  for (const Ring& ring : rings)
    mesh.vertices.insert(mesh.vertices.end(), ring.begin(), ring.end());
  const int first = n * ring_count;
  const int last = first + 1;
  mesh.vertices.push_back(first_cap);
  mesh.vertices.push_back(last_cap);
  auto index = [n](int ring, int j) { return ring * n + (j % n); };
  for (int j = 0; j < n; ++j) {
    mesh.triangles.emplace_back(first, index(0, j + 1), index(0, j));
    for (int i = 0; i + 1 < ring_count; ++i) {
      mesh.triangles.emplace_back(index(i, j), index(i, j + 1), index(i + 1, j + 1));
      mesh.triangles.emplace_back(index(i, j), index(i + 1, j + 1), index(i + 1, j));
    }
    mesh.triangles.emplace_back(last, index(ring_count - 1, j), index(ring_count - 1, j + 1));
  }
  return mesh;
}

// A circle of `segments` points about `center`, counter-clockwise about `axis`.
Ring Circle(const Eigen::Vector3d& center, const Eigen::Vector3d& axis, double radius,
            int segments) {
  const Eigen::Vector3d u = axis.normalized();
  const Eigen::Vector3d e1 = u.unitOrthogonal();
  const Eigen::Vector3d e2 = u.cross(e1);  // e1 x e2 = u: counter-clockwise about u
  Ring ring(segments);
  for (int j = 0; j < segments; ++j) {
    const double phi = 2.0 * kPi * j / segments;
    ring[j] = center + radius * (std::cos(phi) * e1 + std::sin(phi) * e2);
  }
  return ring;
}

// A straight, possibly tapered tube from `from` to `to` with flat end caps. With
// `to_floor`, the end ring is slid along the axis onto z = 0 so the tube stands flat on
// the floor (`to` must then lie on the floor).
TriangleMesh Tube(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double from_radius,
                  double to_radius, int segments, bool to_floor = false) {
  const Eigen::Vector3d axis = to - from;
  Ring end = Circle(to, axis, to_radius, segments);
  if (to_floor) {
    const Eigen::Vector3d u = axis.normalized();
    for (Eigen::Vector3d& p : end) {
      p -= (p.z() / u.z()) * u;
      p.z() = 0.0;  // exactly on the floor, not 1e-13 below it
    }
  }
  return Loft({Circle(from, axis, from_radius, segments), end}, from, to);
}

struct Part {
  std::string name;
  TriangleMesh mesh;
};

// Concatenates the parts and records their triangle ranges in metadata["parts"].
TriangleMesh Assemble(const std::vector<Part>& parts, nlohmann::json& metadata) {
  TriangleMesh mesh;
  metadata["parts"] = nlohmann::json::array();
  for (const Part& part : parts) {
    metadata["parts"].push_back({{"name", part.name},
                                 {"first_triangle", mesh.triangles.size()},
                                 {"triangle_count", part.mesh.triangles.size()}});
    mesh.Append(part.mesh);
  }
  return mesh;
}

Eigen::Affine3d YawAbout(const Eigen::Vector3d& center, double yaw_deg) {
  return Eigen::Translation3d(center) *
         Eigen::AngleAxisd(Radians(yaw_deg), Eigen::Vector3d::UnitZ());
}

// Numbers in messages as a person writes them: 1000, 41.6.
std::string Format(double x) {
  std::ostringstream out;
  out << x;
  return out.str();
}

void Require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument(message);
}

// ---- Mannequin proportions (fractions of the height unless stated) -------------------
// Station heights follow standard anthropometric proportions.
constexpr double kCrotchZ = 0.470;
constexpr double kHipZ = 0.520;
constexpr double kWaistZ = 0.615;
constexpr double kChestZ = 0.720;
constexpr double kShoulderZ = 0.815;
constexpr double kNeckBaseZ = 0.845;
// Depth/width ratios of the torso ellipses.
constexpr double kHipRatio = 0.70;
constexpr double kWaistRatio = 0.74;
constexpr double kChestRatio = 0.70;
constexpr double kCrotchRatio = 0.72;
constexpr double kShoulderRatio = 0.50;
constexpr double kNeckRatio = 0.90;
constexpr double kCrotchWidth = 0.92;    // of the hip half-width
constexpr double kShoulderWidth = 1.12;  // of the chest half-width
constexpr double kNeckHalfWidth = 0.036;
constexpr double kNeckRadius = 0.031;
constexpr double kHeadSemiAxes[3] = {0.046, 0.056, 0.066};  // x, y, z
constexpr double kArmLength = 0.42;
constexpr double kArmTopRadius = 0.026;
constexpr double kArmBottomRadius = 0.018;
constexpr double kArmJointBelowShoulder = 0.02;
constexpr double kArmBuried = 0.03;  // the arm starts this far up its line, in the shoulder
constexpr double kNeckBelowShoulder = 0.015;
constexpr double kAnkleRadius = 0.020;
constexpr double kLegOffset = 0.48;     // leg axis x, of the hip half-width
constexpr double kLegTopRadius = 0.44;  // of the hip half-width
constexpr double kArmGapTarget = 50.0;  // mm; the promise is 40, the polygon only adds
constexpr int kSegments = 256;
constexpr double kMaxRingSpacing = 5.0;  // mm

struct MannequinShape {
  double chest_a, chest_b, waist_a, waist_b, hip_a, hip_b;
  double shoulder_a, arm_angle;  // radians from vertical
};

// Horizontal distance from the torso at height `station_z` (half-width `a`) to the
// nearest point of the (infinitely long) arm tube: a finite tube's horizontal section is
// a subset of the infinite one's, so this is a lower bound on the real gap.
double ArmGap(const MannequinParams& p, const MannequinShape& s, double angle, double station_z,
              double a) {
  const double h = p.height_mm;
  const double joint_z = (kShoulderZ - kArmJointBelowShoulder) * h;
  const double axis_x = s.shoulder_a + (joint_z - station_z) * std::tan(angle);
  return axis_x - kArmTopRadius * h / std::cos(angle) - a;
}

// Semi-axes of the girth stations and the smallest A-pose arm angle (20..50 degrees)
// that keeps the arms kArmGapTarget clear of the torso at all three stations. When no
// angle does, `blocking` names the girth parameter at fault.
std::optional<MannequinShape> SolveMannequin(const MannequinParams& p, std::string* blocking) {
  MannequinShape s{};
  s.chest_a = p.chest_girth_mm / EllipsePerimeter(1.0, kChestRatio);
  s.chest_b = kChestRatio * s.chest_a;
  s.waist_a = p.waist_girth_mm / EllipsePerimeter(1.0, kWaistRatio);
  s.waist_b = kWaistRatio * s.waist_a;
  s.hip_a = p.hip_girth_mm / EllipsePerimeter(1.0, kHipRatio);
  s.hip_b = kHipRatio * s.hip_a;
  s.shoulder_a = kShoulderWidth * s.chest_a;
  const double h = p.height_mm;
  const std::array<std::pair<double, double>, 3> stations = {
      {{kChestZ * h, s.chest_a}, {kWaistZ * h, s.waist_a}, {kHipZ * h, s.hip_a}}};
  const std::array<const char*, 3> names = {"chest_girth_mm", "waist_girth_mm", "hip_girth_mm"};
  if (p.arm_angle_deg) {  // posed: the arms may come as near the torso as asked
    s.arm_angle = Radians(*p.arm_angle_deg);
    return s;
  }
  for (double deg = 20.0; deg <= 50.0 + 1e-9; deg += 0.25) {
    bool clear = true;
    for (size_t k = 0; k < stations.size(); ++k) {
      if (ArmGap(p, s, Radians(deg), stations[k].first, stations[k].second) < kArmGapTarget) {
        clear = false;
        if (blocking) *blocking = names[k];
      }
    }
    if (clear) {
      s.arm_angle = Radians(deg);
      return s;
    }
  }
  return std::nullopt;
}

// Monotone piecewise-cubic (Fritsch–Carlson) interpolation: smooth (C1), exact at the
// knots and free of overshoot, so the torso never bulges past its stations.
class Pchip {
 public:
  Pchip(std::vector<double> x, std::vector<double> y) : x_(std::move(x)), y_(std::move(y)) {
    const size_t n = x_.size();
    std::vector<double> h(n - 1), delta(n - 1);
    for (size_t k = 0; k + 1 < n; ++k) {
      h[k] = x_[k + 1] - x_[k];
      delta[k] = (y_[k + 1] - y_[k]) / h[k];
    }
    m_.assign(n, 0.0);
    m_.front() = delta.front();
    m_.back() = delta.back();
    for (size_t k = 1; k + 1 < n; ++k) {
      if (delta[k - 1] * delta[k] <= 0.0) continue;
      const double w1 = 2.0 * h[k] + h[k - 1];
      const double w2 = h[k] + 2.0 * h[k - 1];
      m_[k] = (w1 + w2) / (w1 / delta[k - 1] + w2 / delta[k]);
    }
  }

  double operator()(double x) const {
    size_t k = 0;
    while (k + 2 < x_.size() && x >= x_[k + 1]) ++k;
    if (x == x_[k]) return y_[k];  // exactly the station value, no rounding
    if (x == x_[k + 1]) return y_[k + 1];
    const double h = x_[k + 1] - x_[k];
    const double t = (x - x_[k]) / h;
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * y_[k] + (t3 - 2 * t2 + t) * h * m_[k] +
           (-2 * t3 + 3 * t2) * y_[k + 1] + (t3 - t2) * h * m_[k + 1];
  }

 private:
  std::vector<double> x_, y_, m_;
};

// The torso's half width and half depth as functions of height, through its stations.
struct TorsoProfile {
  std::vector<double> z;
  Pchip half_width, half_depth;
};

TorsoProfile MakeTorsoProfile(const MannequinParams& p, const MannequinShape& s) {
  const double h = p.height_mm;
  const double neck_a = kNeckHalfWidth * h;
  std::vector<double> z = {kCrotchZ * h, kHipZ * h,      kWaistZ * h,
                           kChestZ * h,  kShoulderZ * h, kNeckBaseZ * h};
  Pchip half_width(z,
                   {kCrotchWidth * s.hip_a, s.hip_a, s.waist_a, s.chest_a, s.shoulder_a, neck_a});
  Pchip half_depth(z, {kCrotchRatio * kCrotchWidth * s.hip_a, s.hip_b, s.waist_b, s.chest_b,
                       kShoulderRatio * s.shoulder_a, kNeckRatio * neck_a});
  return {std::move(z), std::move(half_width), std::move(half_depth)};
}

TriangleMesh MakeTorso(const MannequinParams& p, const MannequinShape& s) {
  const TorsoProfile profile = MakeTorsoProfile(p, s);
  const std::vector<double>& z = profile.z;
  const Pchip& half_width = profile.half_width;
  const Pchip& half_depth = profile.half_depth;
  std::vector<Ring> rings;
  for (size_t k = 0; k + 1 < z.size(); ++k) {
    const int steps = static_cast<int>(std::ceil((z[k + 1] - z[k]) / kMaxRingSpacing));
    // Every station is a ring of its own, so its girth is exactly the solved ellipse's.
    const int end = (k + 2 == z.size()) ? steps : steps - 1;
    for (int i = 0; i <= end; ++i) {
      const double zi = (i == 0)       ? z[k]
                        : (i == steps) ? z[k + 1]
                                       : z[k] + (z[k + 1] - z[k]) * i / steps;
      const double a = half_width(zi), b = half_depth(zi);
      Ring ring(kSegments);
      for (int j = 0; j < kSegments; ++j) {
        const double phi = 2.0 * kPi * j / kSegments;
        ring[j] = Eigen::Vector3d(a * std::cos(phi), b * std::sin(phi), zi);
      }
      rings.push_back(std::move(ring));
    }
  }
  return Loft(rings, Eigen::Vector3d(0, 0, z.front()), Eigen::Vector3d(0, 0, z.back()));
}

TriangleMesh MakeHead(double height) {
  const double ax = kHeadSemiAxes[0] * height, ay = kHeadSemiAxes[1] * height,
               az = kHeadSemiAxes[2] * height;
  const double center_z = height - az;
  const int latitudes = kSegments / 2;
  std::vector<Ring> rings;
  for (int i = 1; i < latitudes; ++i) {
    const double theta = kPi * i / latitudes;  // from the bottom pole
    Ring ring(kSegments);
    for (int j = 0; j < kSegments; ++j) {
      const double phi = 2.0 * kPi * j / kSegments;
      ring[j] =
          Eigen::Vector3d(ax * std::sin(theta) * std::cos(phi),
                          ay * std::sin(theta) * std::sin(phi), center_z - az * std::cos(theta));
    }
    rings.push_back(std::move(ring));
  }
  // The top pole is set, not computed, so the head's top is exactly at `height`.
  return Loft(rings, Eigen::Vector3d(0, 0, center_z - az), Eigen::Vector3d(0, 0, height));
}

// The mannequin's parts as solids in its own frame (facing -y, before yaw and centring):
// what MakeMannequin tessellates, for truth taken from the shapes rather than the mesh.
class MannequinSolid {
 public:
  MannequinSolid(const MannequinParams& p, const MannequinShape& s)
      : p_(p), s_(s), torso_(MakeTorsoProfile(p, s)), h_(p.height_mm) {}

  double h() const { return h_; }
  const MannequinShape& shape() const { return s_; }
  bool ArmsRaised() const { return s_.arm_angle > kPi / 2; }
  double TorsoGirth(double z) const {
    return EllipsePerimeter(torso_.half_width(z), torso_.half_depth(z));
  }
  double TorsoDepth(double z) const { return torso_.half_depth(z); }
  double LegTopZ() const { return 0.5 * (kCrotchZ + kHipZ) * h_; }
  double LegRadius(double z) const {
    const double top = kLegTopRadius * s_.hip_a, floor = kAnkleRadius * h_;
    return floor + (top - floor) * z / LegTopZ();
  }
  Eigen::Vector3d ArmJoint(double side) const {
    return {side * s_.shoulder_a, 0.0, (kShoulderZ - kArmJointBelowShoulder) * h_};
  }
  Eigen::Vector3d ArmDown(double side) const {
    return {side * std::sin(s_.arm_angle), 0.0, -std::cos(s_.arm_angle)};
  }
  // Radius of the arm tube at distance t along its axis from its buried start.
  double ArmRadius(double t) const {
    const double length = (kArmBuried + kArmLength) * h_;
    return kArmTopRadius * h_ + (kArmBottomRadius - kArmTopRadius) * h_ * t / length;
  }

  bool Inside(const Eigen::Vector3d& q) const {
    const double z = q.z();
    if (z >= kCrotchZ * h_ && z <= kNeckBaseZ * h_) {
      const double a = torso_.half_width(z), b = torso_.half_depth(z);
      if (std::pow(q.x() / a, 2) + std::pow(q.y() / b, 2) <= 1.0) return true;
    }
    for (const double side : {1.0, -1.0}) {
      const double leg_x = side * kLegOffset * s_.hip_a;
      if (z >= 0.0 && z <= LegTopZ() && std::hypot(q.x() - leg_x, q.y()) <= LegRadius(z)) {
        return true;
      }
      const Eigen::Vector3d start = ArmJoint(side) - kArmBuried * h_ * ArmDown(side);
      const double t = (q - start).dot(ArmDown(side));
      if (t >= 0.0 && t <= (kArmBuried + kArmLength) * h_ &&
          (q - start - t * ArmDown(side)).norm() <= ArmRadius(t)) {
        return true;
      }
    }
    const double head_center_z = h_ - kHeadSemiAxes[2] * h_;
    if (z >= (kShoulderZ - kNeckBelowShoulder) * h_ && z <= head_center_z &&
        std::hypot(q.x(), q.y()) <= kNeckRadius * h_) {
      return true;
    }
    return std::pow(q.x() / (kHeadSemiAxes[0] * h_), 2) +
               std::pow(q.y() / (kHeadSemiAxes[1] * h_), 2) +
               std::pow((z - head_center_z) / (kHeadSemiAxes[2] * h_), 2) <=
           1.0;
  }

  // Where the line from `inside` along `direction` first leaves the body (to 0.001 mm).
  Eigen::Vector3d Exit(const Eigen::Vector3d& inside, const Eigen::Vector3d& direction) const {
    double t = 0.0;
    while (Inside(inside + (t + 0.25) * direction)) t += 0.25;
    double lo = t, hi = t + 0.25;
    while (hi - lo > 1e-4) {
      const double mid = 0.5 * (lo + hi);
      (Inside(inside + mid * direction) ? lo : hi) = mid;
    }
    return inside + lo * direction;
  }

  // Lower bound on the horizontal gap between the torso and either hanging arm at z.
  double ArmGapAt(double z) const { return ArmGap(p_, s_, s_.arm_angle, z, torso_.half_width(z)); }

 private:
  MannequinParams p_;
  MannequinShape s_;
  TorsoProfile torso_;
  double h_;
};

// The z in [lo, hi] where f is largest, to 0.01 mm (f has one peak there).
template <typename F>
double ArgMax(F f, double lo, double hi) {
  double best = lo;
  for (double z = lo; z <= hi; z += 0.5) {
    if (f(z) > f(best)) best = z;
  }
  double a = std::max(lo, best - 0.5), b = std::min(hi, best + 0.5);
  for (double step = 0.01; b - a > step;) {
    const double m1 = a + (b - a) / 3, m2 = b - (b - a) / 3;
    if (f(m1) < f(m2)) {
      a = m1;
    } else {
      b = m2;
    }
  }
  return 0.5 * (a + b);
}

// Height of the thigh girth below the crotch, and the fraction of the shoulder-to-wrist
// length at which the upper-arm girth is taken: host/measurement's definitions.
constexpr double kThighBelowCrotchMm = 20.0;
constexpr double kUpperArmFraction = 0.275;

// The girth recorded is the ellipse's own perimeter, not the request, so ground truth is
// what the mesh models even if the solve were off.
nlohmann::json StationJson(double z, double a, double b) {
  return {{"girth_mm", EllipsePerimeter(a, b)}, {"z_mm", z}, {"semi_axes_mm", {a, b}}};
}

}  // namespace

double EllipsePerimeter(double a, double b) {
  a = std::abs(a);
  b = std::abs(b);
  if (a < b) std::swap(a, b);
  if (b == 0.0) return 4.0 * a;
  // Gauss–Legendre AGM: C = 2 pi / AGM(a, b) * (a^2 - sum 2^(n-1) c_n^2).
  double sum = 0.5 * (a * a - b * b);
  double weight = 0.5;
  const double a2 = a * a;
  for (int n = 0; n < 64; ++n) {
    const double c = 0.5 * (a - b);
    const double next_b = std::sqrt(a * b);
    a = 0.5 * (a + b);
    b = next_b;
    weight *= 2.0;
    sum += weight * c * c;
    if (c <= 1e-12 * a) break;  // the next term is below 1e-24 a
  }
  return 2.0 * kPi * (a2 - sum) / a;
}

Subject MakeNoSubject() {
  return {
      "none",
      {},
      {{"type", "none"}, {"params", nlohmann::json::object()}, {"parts", nlohmann::json::array()}},
      {}};
}

Subject MakeCuboidOnTripod(const CuboidParams& p) {
  Require((p.size_mm.array() > 0.0).all(), "cuboid: size must be positive");
  const double underside = p.center_mm.z() - 0.5 * p.size_mm.z();
  Require(underside >= 300.0, "cuboid: the tripod needs the underside at least 300 mm up");
  const Eigen::Affine3d world_from_body = YawAbout(p.center_mm, p.yaw_deg);

  Subject subject{"cuboid", {}, {}, {}};
  nlohmann::json& meta = subject.metadata;
  meta["type"] = "cuboid";
  meta["params"] = {
      {"size_mm", ToJson(p.size_mm)}, {"center_mm", ToJson(p.center_mm)}, {"yaw_deg", p.yaw_deg}};
  meta["size_mm"] = ToJson(p.size_mm);
  meta["center_mm"] = ToJson(p.center_mm);
  meta["yaw_deg"] = p.yaw_deg;

  // Corner i: + on x, y, z where bit 0, 1, 2 of i is set. Two triangles per face through
  // the corners only, so every face is exactly planar.
  TriangleMesh cuboid;
  meta["corners_mm"] = nlohmann::json::array();
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d sign((i & 1) ? 0.5 : -0.5, (i & 2) ? 0.5 : -0.5, (i & 4) ? 0.5 : -0.5);
    cuboid.vertices.push_back(world_from_body * sign.cwiseProduct(p.size_mm).eval());
    meta["corners_mm"].push_back(ToJson(cuboid.vertices.back()));
  }
  cuboid.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 5}, {0, 5, 4},
                      {2, 7, 3}, {2, 6, 7}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};

  // Tripod: a head 120 mm under the cuboid, a column from below the head up into the
  // cuboid, three legs splayed 22 degrees from the head to the floor. One leg points at
  // the camera, the others at the two mirror views.
  constexpr int kTubeSegments = 64;
  constexpr double kLegRadius = 12.0, kColumnRadius = 16.0, kSplay = 22.0;
  const double head_z = underside - 120.0;
  const Eigen::Vector3d axis(p.center_mm.x(), p.center_mm.y(), 0.0);
  std::vector<Part> parts = {{"cuboid", cuboid}};
  parts.push_back({"column", Tube(axis + Eigen::Vector3d(0, 0, head_z - 40.0),
                                  axis + Eigen::Vector3d(0, 0, underside + 20.0), kColumnRadius,
                                  kColumnRadius, kTubeSegments)});
  for (int leg = 0; leg < 3; ++leg) {
    const double azimuth = Radians(p.yaw_deg - 90.0 + 120.0 * leg);
    const Eigen::Vector3d out(std::cos(azimuth), std::sin(azimuth), 0.0);
    const Eigen::Vector3d top = axis + 20.0 * out + Eigen::Vector3d(0, 0, head_z);
    const Eigen::Vector3d foot = axis + (20.0 + head_z * std::tan(Radians(kSplay))) * out;
    // Start 30 mm up the leg's line so its end is buried in the head.
    const Eigen::Vector3d start = top + 30.0 * (top - foot).normalized();
    parts.push_back({"leg" + std::to_string(leg + 1),
                     Tube(start, foot, kLegRadius, kLegRadius, kTubeSegments, true)});
  }
  subject.mesh = Assemble(parts, meta);
  return subject;
}

Subject MakeCylinder(const CylinderParams& p) {
  Require(p.radius_mm > 0.0 && p.height_mm > 0.0 && p.bottom_mm >= 0.0,
          "cylinder: radius and height must be positive and the bottom not below the floor");
  constexpr int kCylinderSegments = 720;
  const double top = p.bottom_mm + p.height_mm;
  std::vector<Ring> rings(2, Ring(kCylinderSegments));
  for (int j = 0; j < kCylinderSegments; ++j) {
    const double phi = 2.0 * kPi * j / kCylinderSegments;
    const double x = p.center_mm.x() + p.radius_mm * std::cos(phi);
    const double y = p.center_mm.y() + p.radius_mm * std::sin(phi);
    rings[0][j] = Eigen::Vector3d(x, y, p.bottom_mm);
    rings[1][j] = Eigen::Vector3d(x, y, top);
  }
  Subject subject{"cylinder", {}, {}, {}};
  subject.metadata = {{"type", "cylinder"},
                      {"params",
                       {{"radius_mm", p.radius_mm},
                        {"height_mm", p.height_mm},
                        {"bottom_mm", p.bottom_mm},
                        {"center_mm", ToJson(p.center_mm)}}},
                      {"segments", kCylinderSegments}};
  subject.mesh = Assemble(
      {{"cylinder", Loft(rings, Eigen::Vector3d(p.center_mm.x(), p.center_mm.y(), p.bottom_mm),
                         Eigen::Vector3d(p.center_mm.x(), p.center_mm.y(), top))}},
      subject.metadata);
  return subject;
}

Subject MakeMannequin(const MannequinParams& p) {
  Require(
      p.height_mm > 0.0 && p.chest_girth_mm > 0.0 && p.waist_girth_mm > 0.0 && p.hip_girth_mm > 0.0,
      "mannequin: height and girths must be positive");
  std::string blocking;
  const std::optional<MannequinShape> shape = SolveMannequin(p, &blocking);
  Require(shape.has_value(), "mannequin: " + blocking + " leaves no room for the arms");
  Require(!p.arm_angle_deg || (*p.arm_angle_deg >= 4.0 && *p.arm_angle_deg <= 60.0) ||
              (*p.arm_angle_deg >= 100.0 && *p.arm_angle_deg <= 150.0),
          "mannequin: the arm angle must hang the arms (4..60) or raise them (100..150)");
  const MannequinShape& s = *shape;
  const double h = p.height_mm;

  // Built facing -y (the camera) about the z axis, then yawed and moved as a whole.
  // "left"/"right" are the mannequin's own: its left arm is at +x, the camera's right.
  std::vector<Part> parts = {{"torso", MakeTorso(p, s)}};
  const double crotch_z = kCrotchZ * h, hip_z = kHipZ * h;
  for (const double side : {1.0, -1.0}) {
    const std::string name = side > 0 ? "left" : "right";
    // Legs stop halfway between crotch and hip, buried in the torso, so a girth at the
    // hip station never cuts them.
    const double leg_x = side * kLegOffset * s.hip_a;
    parts.push_back({name + "_leg", Tube(Eigen::Vector3d(leg_x, 0, 0.5 * (crotch_z + hip_z)),
                                         Eigen::Vector3d(leg_x, 0, 0), kLegTopRadius * s.hip_a,
                                         kAnkleRadius * h, kSegments, true)});
  }
  for (const double side : {1.0, -1.0}) {
    const std::string name = side > 0 ? "left" : "right";
    const Eigen::Vector3d joint(side * s.shoulder_a, 0.0,
                                (kShoulderZ - kArmJointBelowShoulder) * h);
    const Eigen::Vector3d down(side * std::sin(s.arm_angle), 0.0, -std::cos(s.arm_angle));
    // The arm starts a little up its own line so its end is buried in the shoulder.
    parts.push_back(
        {name + "_arm", Tube(joint - kArmBuried * h * down, joint + kArmLength * h * down,
                             kArmTopRadius * h, kArmBottomRadius * h, kSegments)});
  }
  const double head_center_z = h - kHeadSemiAxes[2] * h;
  parts.push_back({"neck", Tube(Eigen::Vector3d(0, 0, (kShoulderZ - kNeckBelowShoulder) * h),
                                Eigen::Vector3d(0, 0, head_center_z), kNeckRadius * h,
                                kNeckRadius * h, kSegments)});
  parts.push_back({"head", MakeHead(h)});

  Subject subject{"mannequin", {}, {}, {}};
  nlohmann::json& meta = subject.metadata;
  meta["type"] = "mannequin";
  meta["params"] = {{"height_mm", p.height_mm},           {"chest_girth_mm", p.chest_girth_mm},
                    {"waist_girth_mm", p.waist_girth_mm}, {"hip_girth_mm", p.hip_girth_mm},
                    {"center_mm", ToJson(p.center_mm)},   {"yaw_deg", p.yaw_deg}};
  meta["params"]["arm_angle_deg"] =
      p.arm_angle_deg ? nlohmann::json(*p.arm_angle_deg) : nlohmann::json(nullptr);
  meta["height_mm"] = h;
  meta["arm_angle_deg"] = s.arm_angle * 180.0 / kPi;
  meta["chest"] = StationJson(kChestZ * h, s.chest_a, s.chest_b);
  meta["waist"] = StationJson(kWaistZ * h, s.waist_a, s.waist_b);
  meta["hip"] = StationJson(kHipZ * h, s.hip_a, s.hip_b);
  meta["truth"] = MannequinMeasurementTruth(p);
  subject.mesh = Assemble(parts, meta);
  subject.mesh.Transform(
      YawAbout(Eigen::Vector3d(p.center_mm.x(), p.center_mm.y(), 0.0), p.yaw_deg));
  return subject;
}

namespace {

MannequinSolid SolidOf(const MannequinParams& p) {
  std::string blocking;
  const std::optional<MannequinShape> shape = SolveMannequin(p, &blocking);
  Require(shape.has_value(), "mannequin: " + blocking + " leaves no room for the arms");
  return MannequinSolid(p, *shape);
}

}  // namespace

nlohmann::json MannequinMeasurementTruth(const MannequinParams& p) {
  const MannequinSolid body = SolidOf(p);
  const double h = body.h();
  const double crotch = kCrotchZ * h, hip = kHipZ * h, waist = kWaistZ * h;
  const double chest = kChestZ * h, shoulder = kShoulderZ * h;
  auto girth = [&body](double z) { return body.TorsoGirth(z); };
  const double hip_z = ArgMax(girth, crotch, waist);
  const double waist_z = ArgMax([&](double z) { return -girth(z); }, hip, chest);
  const double chest_z = ArgMax([&](double z) { return body.TorsoDepth(z); }, waist, shoulder);
  const double thigh_z = crotch - kThighBelowCrotchMm;
  nlohmann::json truth = {{"stature_mm", h},
                          {"crotch_height_mm", crotch},
                          {"hip_girth_mm", girth(hip_z)},
                          {"hip_z_mm", hip_z},
                          {"waist_girth_mm", girth(waist_z)},
                          {"waist_z_mm", waist_z},
                          {"chest_girth_mm", girth(chest_z)},
                          {"chest_z_mm", chest_z},
                          {"thigh_girth_mm", 2.0 * kPi * body.LegRadius(thigh_z)},
                          {"thigh_z_mm", thigh_z},
                          {"neck_girth_mm", 2.0 * kPi * kNeckRadius * h}};
  const Eigen::Affine3d world_from_body =
      YawAbout(Eigen::Vector3d(p.center_mm.x(), p.center_mm.y(), 0.0), p.yaw_deg);
  if (body.ArmsRaised()) {
    for (const char* key : {"upper_arm_girth_mm", "shoulder_breadth_mm", "arm_length_mm",
                            "shoulder_points_mm", "wrist_points_mm"}) {
      truth[key] = nullptr;
    }
    return truth;
  }
  // Shoulder point: where the arm's axis, followed up past the joint, leaves the body.
  std::array<Eigen::Vector3d, 2> shoulder_points, wrist_points;
  for (int k = 0; k < 2; ++k) {
    const double side = k == 0 ? 1.0 : -1.0;
    const Eigen::Vector3d joint = body.ArmJoint(side), down = body.ArmDown(side);
    shoulder_points[k] = body.Exit(joint, -down);
    wrist_points[k] = joint + kArmLength * h * down;
  }
  const Eigen::Vector3d& s = shoulder_points[0];
  const Eigen::Vector3d& w = wrist_points[0];
  const Eigen::Vector3d upper_arm = s + kUpperArmFraction * (w - s);
  const Eigen::Vector3d arm_start = body.ArmJoint(1.0) - kArmBuried * h * body.ArmDown(1.0);
  truth["upper_arm_girth_mm"] =
      2.0 * kPi * body.ArmRadius((upper_arm - arm_start).dot(body.ArmDown(1.0)));
  truth["shoulder_breadth_mm"] = (shoulder_points[0] - shoulder_points[1]).norm();
  truth["arm_length_mm"] = (s - w).norm();
  truth["shoulder_points_mm"] = {ToJson((world_from_body * shoulder_points[0]).eval()),
                                 ToJson((world_from_body * shoulder_points[1]).eval())};
  truth["wrist_points_mm"] = {ToJson((world_from_body * wrist_points[0]).eval()),
                              ToJson((world_from_body * wrist_points[1]).eval())};
  return truth;
}

std::optional<GirthTruth> MannequinGirthTruth(const MannequinParams& p, double z) {
  const MannequinSolid body = SolidOf(p);
  const double h = body.h();
  if (z > 0.0 && z < kCrotchZ * h) return GirthTruth{"left_leg", 2.0 * kPi * body.LegRadius(z)};
  if (z < kCrotchZ * h || z > kChestZ * h) return std::nullopt;
  if (!body.ArmsRaised() && body.ArmGapAt(z) <= 0.0) return std::nullopt;
  return GirthTruth{"torso", body.TorsoGirth(z)};
}

Subject LoadMeshSubject(const MeshParams& p) {
  Require(p.scale > 0.0, "mesh: scale must be positive");
  Subject subject{"mesh", {}, {}, {}};
  try {
    subject.mesh = ReadTriangleMesh(p.path);
  } catch (const MeshIoError& e) {
    throw ConfigError(e.what());
  }
  const Eigen::Vector3d r = p.rotation_deg;
  const Eigen::Affine3d world_from_file =
      Eigen::Translation3d(p.translation_mm) *
      Eigen::AngleAxisd(Radians(r.z()), Eigen::Vector3d::UnitZ()) *
      Eigen::AngleAxisd(Radians(r.y()), Eigen::Vector3d::UnitY()) *
      Eigen::AngleAxisd(Radians(r.x()), Eigen::Vector3d::UnitX()) * Eigen::Scaling(p.scale);
  subject.mesh.Transform(world_from_file);
  subject.metadata = {{"type", "mesh"},
                      {"params",
                       {{"path", p.path.string()},
                        {"scale", p.scale},
                        {"translation_mm", ToJson(p.translation_mm)},
                        {"rotation_deg", ToJson(p.rotation_deg)}}},
                      {"vertex_count", subject.mesh.vertices.size()},
                      {"triangle_count", subject.mesh.triangles.size()}};
  // A loaded mesh is one part: nothing says how its pieces divide.
  subject.metadata["parts"] = {
      {{"name", "mesh"}, {"first_triangle", 0}, {"triangle_count", subject.mesh.triangles.size()}}};
  return subject;
}

Subject ParseSubject(const JsonReader& json, const std::filesystem::path& base_dir) {
  const std::string type =
      json.Choice("type", {"cuboid", "cylinder", "mannequin", "body", "mesh", "none"});
  auto vector3 = [&json](const char* key, const Eigen::Vector3d& fallback) {
    const std::vector<double> v =
        json.Numbers(key, 3, std::vector<double>{fallback.x(), fallback.y(), fallback.z()});
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  auto vector2 = [&json](const char* key, const Eigen::Vector2d& fallback) {
    const std::vector<double> v =
        json.Numbers(key, 2, std::vector<double>{fallback.x(), fallback.y()});
    return Eigen::Vector2d(v[0], v[1]);
  };
  if (type == "none") {
    json.AllowOnly({"type"});
    return MakeNoSubject();
  }
  if (type == "cuboid") {
    json.AllowOnly({"type", "size_mm", "center_mm", "yaw_deg"});
    CuboidParams p;
    p.size_mm = vector3("size_mm", p.size_mm);
    if ((p.size_mm.array() <= 0.0).any()) json.Fail("size_mm", "every size must be positive");
    p.center_mm = vector3("center_mm", p.center_mm);
    const double underside = p.center_mm.z() - 0.5 * p.size_mm.z();
    if (underside < 300.0) {
      json.Fail("center_mm", "puts the cuboid's underside at z = " + Format(underside) +
                                 " mm; its tripod needs at least 300 mm");
    }
    p.yaw_deg = json.Number("yaw_deg", p.yaw_deg, -360.0, 360.0);
    return MakeCuboidOnTripod(p);
  }
  if (type == "cylinder") {
    json.AllowOnly({"type", "radius_mm", "height_mm", "bottom_mm", "center_mm"});
    CylinderParams p;
    p.radius_mm = json.Number("radius_mm", p.radius_mm, 1.0, 2000.0);
    p.height_mm = json.Number("height_mm", p.height_mm, 1.0, 3000.0);
    p.bottom_mm = json.Number("bottom_mm", p.bottom_mm, 0.0, 3000.0);
    p.center_mm = vector2("center_mm", p.center_mm);
    return MakeCylinder(p);
  }
  if (type == "mannequin") {
    json.AllowOnly({"type", "height_mm", "chest_girth_mm", "waist_girth_mm", "hip_girth_mm",
                    "center_mm", "yaw_deg", "arm_angle_deg"});
    MannequinParams p;
    p.height_mm = json.Number("height_mm", p.height_mm, 1000.0, 2300.0);
    p.chest_girth_mm = json.Number("chest_girth_mm", p.chest_girth_mm, 500.0, 1800.0);
    p.waist_girth_mm = json.Number("waist_girth_mm", p.waist_girth_mm, 400.0, 1800.0);
    p.hip_girth_mm = json.Number("hip_girth_mm", p.hip_girth_mm, 500.0, 1800.0);
    p.center_mm = vector2("center_mm", p.center_mm);
    p.yaw_deg = json.Number("yaw_deg", p.yaw_deg, -360.0, 360.0);
    if (json.Has("arm_angle_deg")) {
      p.arm_angle_deg = json.Number("arm_angle_deg", std::nullopt, 4.0, 150.0);
      if (*p.arm_angle_deg > 60.0 && *p.arm_angle_deg < 100.0) {
        json.Fail("arm_angle_deg", "must hang the arms (4..60) or raise them (100..150)");
      }
    }
    std::string blocking;
    if (!SolveMannequin(p, &blocking)) {
      json.Fail(blocking, "too large for height_mm " + Format(p.height_mm) +
                              ": the arms cannot hang clear of the torso");
    }
    return MakeMannequin(p);
  }
  if (type == "body") {
    json.AllowOnly({"type",
                    "sex",
                    "stature_mm",
                    "chest_girth_mm",
                    "underbust_girth_mm",
                    "waist_girth_mm",
                    "hip_girth_mm",
                    "thigh_girth_mm",
                    "upper_arm_girth_mm",
                    "neck_girth_mm",
                    "shoulder_breadth_mm",
                    "leg_length_mm",
                    "belly",
                    "bust",
                    "arm_abduction_deg",
                    "elbow_bend_deg",
                    "feet_apart_mm",
                    "yaw_deg",
                    "lean_deg",
                    "head_turn_deg",
                    "hands",
                    "center_mm",
                    "skin_albedo",
                    "hair_albedo",
                    "underwear_albedo",
                    "cell_mm",
                    "name"});
    BodyParams p;
    p.sex = json.Choice("sex", {"male", "female"}, p.sex);
    p.hands = json.Choice("hands", {"fist", "open"}, p.hands);
    auto number = [&json](const char* key, double& value) { value = json.Number(key, value); };
    number("stature_mm", p.stature_mm);
    number("chest_girth_mm", p.chest_girth_mm);
    number("underbust_girth_mm", p.underbust_girth_mm);
    number("waist_girth_mm", p.waist_girth_mm);
    number("hip_girth_mm", p.hip_girth_mm);
    number("thigh_girth_mm", p.thigh_girth_mm);
    number("upper_arm_girth_mm", p.upper_arm_girth_mm);
    number("neck_girth_mm", p.neck_girth_mm);
    number("shoulder_breadth_mm", p.shoulder_breadth_mm);
    number("leg_length_mm", p.leg_length_mm);
    number("belly", p.belly);
    number("bust", p.bust);
    number("arm_abduction_deg", p.arm_abduction_deg);
    number("elbow_bend_deg", p.elbow_bend_deg);
    number("feet_apart_mm", p.feet_apart_mm);
    number("yaw_deg", p.yaw_deg);
    number("lean_deg", p.lean_deg);
    number("head_turn_deg", p.head_turn_deg);
    number("skin_albedo", p.skin_albedo);
    number("hair_albedo", p.hair_albedo);
    number("underwear_albedo", p.underwear_albedo);
    p.center_mm = vector2("center_mm", p.center_mm);
    const double cell = json.Number("cell_mm", 4.0, 2.0, 10.0);
    if (json.Has("name")) json.String("name");
    try {
      p.Validate();
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      const size_t colon = message.find(':');
      json.Fail(message.substr(0, colon), message.substr(colon + 2));
    }
    Subject subject = MakeBody(p, cell);
    if (json.Has("name")) subject.metadata["name"] = json.String("name");
    return subject;
  }
  // type == "mesh"
  json.AllowOnly({"type", "path", "scale", "translation_mm", "rotation_deg"});
  MeshParams p;
  p.path = json.String("path");
  if (p.path.empty()) json.Fail("path", "must not be empty");
  if (p.path.is_relative() && !base_dir.empty()) p.path = base_dir / p.path;
  p.scale = json.Number("scale", p.scale, 1e-9, 1e9);
  if (p.scale <= 0.0) json.Fail("scale", "must be positive");
  p.translation_mm = vector3("translation_mm", p.translation_mm);
  p.rotation_deg = vector3("rotation_deg", p.rotation_deg);
  try {
    return LoadMeshSubject(p);
  } catch (const ConfigError& e) {
    json.Fail("path", e.what());
  }
}

}  // namespace mirrorscan::virtual_cabinet

#include "boards/virtual/body_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "boards/virtual/body_truth.h"
#include "boards/virtual/isosurface.h"
#include "boards/virtual/subjects.h"

namespace mirrorscan::virtual_cabinet {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
double Radians(double degrees) { return degrees * kPi / 180.0; }

// Polynomial smooth minimum: equal to min(a, b) where they differ by more than k, a
// rounded fillet of about k/4 where they meet.
double SmoothMin(double a, double b, double k) {
  if (k <= 0) return std::min(a, b);
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double SmoothMax(double a, double b, double k) { return -SmoothMin(-a, -b, k); }

// Signed distance to the convex hull of two spheres (a tapered capsule), exact: in the
// plane of the axis and the point, the surface is two circles and their common tangent.
double RoundCone(const Vector3d& p, const Vector3d& a, const Vector3d& b, double ra, double rb) {
  const Vector3d axis = b - a;
  const double length = axis.norm();
  const Vector3d u = axis / length;
  const double t = (p - a).dot(u);
  const double q = (p - a - t * u).norm();
  const double sin_theta = std::clamp((ra - rb) / length, -0.999, 0.999);
  const double cos_theta = std::sqrt(1 - sin_theta * sin_theta);
  const double along = t * cos_theta - q * sin_theta;  // along the tangent line from a's circle
  if (along < 0) return std::hypot(t, q) - ra;
  if (along > length * cos_theta) return std::hypot(t - length, q) - rb;
  return t * sin_theta + q * cos_theta - ra;
}

// An ellipsoid's distance to first order (the implicit (|x/r| - 1) over its gradient);
// exact on the surface, close to it nearby.
double EllipsoidDistance(const Vector3d& local, const Vector3d& semi) {
  const double k0 = (local.array() / semi.array()).matrix().norm();
  const double k1 = (local.array() / semi.array().square()).matrix().norm();
  if (k1 < 1e-12) return -semi.minCoeff();
  return k0 * (k0 - 1.0) / k1;
}

// The same in 2D for the torso's elliptic sections.
double EllipseDistance(const Vector2d& local, double a, double b) {
  const double k0 = std::hypot(local.x() / a, local.y() / b);
  const double k1 = std::hypot(local.x() / (a * a), local.y() / (b * b));
  if (k1 < 1e-12) return -std::min(a, b);
  return k0 * (k0 - 1.0) / k1;
}

// Groups of primitives (a field may leave some out, e.g. the arms while solving the torso).
enum Group : unsigned {
  kTrunk = 1,
  kHead = 2,
  kLeftArm = 4,
  kRightArm = 8,
  kLeftLeg = 16,
  kRightLeg = 32,
  kAll = 63
};
enum Region { kSkin, kHairRegion, kUnderwear };

struct Primitive {
  enum Kind { kCone, kEllipsoid } kind;
  unsigned group;
  int segment;         // which rigid frame it moves with: 0 body, 1 feet (no lean), 2 head (turn)
  double blend_mm;     // smooth union with what came before
  bool carve = false;  // subtracted instead (a groove)
  Vector3d a = Vector3d::Zero(), b = Vector3d::Zero();  // cone ends, or ellipsoid centre (a)
  double ra = 0, rb = 0;
  Matrix3d axes = Matrix3d::Identity();  // ellipsoid: columns are its local axes
  Vector3d semi = Vector3d::Ones();
  Vector3d bound_center = Vector3d::Zero();
  double bound_radius = 0;

  double Distance(const Vector3d& p) const {
    if (kind == kCone) return RoundCone(p, a, b, ra, rb);
    return EllipsoidDistance(axes.transpose() * (p - a), semi);
  }
  void ComputeBound() {
    if (kind == kCone) {
      bound_center = 0.5 * (a + b);
      bound_radius = 0.5 * (b - a).norm() + std::max(ra, rb);
    } else {
      bound_center = a;
      bound_radius = semi.maxCoeff();
    }
  }
};

// A monotone cubic through the torso's stations (Fritsch-Carlson), so sections never
// overshoot between them.
class Profile {
 public:
  void Set(std::vector<double> z, std::vector<double> value) {
    z_ = std::move(z);
    v_ = std::move(value);
    const size_t n = z_.size();
    std::vector<double> slope(n - 1);
    for (size_t i = 0; i + 1 < n; ++i) slope[i] = (v_[i + 1] - v_[i]) / (z_[i + 1] - z_[i]);
    m_.assign(n, 0.0);
    m_[0] = slope[0];
    m_[n - 1] = slope[n - 2];
    for (size_t i = 1; i + 1 < n; ++i)
      m_[i] = slope[i - 1] * slope[i] <= 0 ? 0.0 : 0.5 * (slope[i - 1] + slope[i]);
    for (size_t i = 0; i + 1 < n; ++i) {
      if (slope[i] == 0) {
        m_[i] = m_[i + 1] = 0;
        continue;
      }
      const double alpha = m_[i] / slope[i], beta = m_[i + 1] / slope[i];
      const double s = alpha * alpha + beta * beta;
      if (s > 9) {
        const double tau = 3 / std::sqrt(s);
        m_[i] = tau * alpha * slope[i];
        m_[i + 1] = tau * beta * slope[i];
      }
    }
  }
  double operator()(double z) const {
    if (z <= z_.front()) return v_.front();
    if (z >= z_.back()) return v_.back();
    const size_t i = std::upper_bound(z_.begin(), z_.end(), z) - z_.begin() - 1;
    const double h = z_[i + 1] - z_[i], t = (z - z_[i]) / h;
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * v_[i] + (t3 - 2 * t2 + t) * h * m_[i] +
           (-2 * t3 + 3 * t2) * v_[i + 1] + (t3 - t2) * h * m_[i + 1];
  }

 private:
  std::vector<double> z_, v_, m_;
};

// Proportions of stature (Drillis & Contini 1966, as tabulated in Winter, "Biomechanics and
// Motor Control of Human Movement", Fig. 4.1; ANSUR II 2012 means for the heights ISO 8559-1
// names: Gordon et al. 2014). docs/virtual-cabinet.md lists them.
struct Proportions {
  static constexpr double kAnkle = 0.039, kKnee = 0.285, kHipJointAboveCrotch = 0.040,
                          kWaist = 0.615, kUnderbust = 0.690, kChest = 0.720, kArmpit = 0.748,
                          kAcromion = 0.818, kCervicale = 0.848, kNeckGirth = 0.856, kChin = 0.870,
                          kUpperArm = 0.186, kForearm = 0.146, kFootLength = 0.152,
                          kFootBreadth = 0.055, kHeadBreadth = 0.089, kHeadLength = 0.112,
                          kHeadHeight = 0.130;
};

}  // namespace

struct BodyField::Impl {
  BodyParams p;
  BodyLandmarks marks;
  double H = 0;
  // Torso sections: the stations' scales are solved for the girths.
  struct Station {
    double z, a, b, c;  // height, half width, half depth, centre's y
  };
  std::vector<Station> stations;
  Profile section_a, section_b, section_c;
  double torso_bottom = 0, torso_top = 0, neck_base = 0;
  double shoulder_half = 0;  // S/2
  std::vector<Primitive> primitives;
  // Rigid frames: world point -> body frame, per segment.
  Eigen::Affine3d world_from_body = Eigen::Affine3d::Identity();
  Eigen::Affine3d body_from_world = Eigen::Affine3d::Identity();
  Eigen::Affine3d lean = Eigen::Affine3d::Identity();       // body (upright) -> leaning
  Eigen::Affine3d head_turn = Eigen::Affine3d::Identity();  // head (straight) -> turned
  Eigen::Affine3d unlean = Eigen::Affine3d::Identity(), unturn = Eigen::Affine3d::Identity();
  // Solved scales.
  double chest_scale = 1, underbust_scale = 1, waist_scale = 1, hip_scale = 1, thigh_scale = 1,
         arm_scale = 1, neck_scale = 1;
  double crotch_z = 0, hip_joint_x = 0, ankle_x = 0;
  Vector3d head_center;
  Vector3d head_semi;
  // Joints in the upright body frame (PlaceLandmarks takes them to world).
  std::array<Vector3d, 2> shoulder_b, elbow_b, wrist_b, hip_b, knee_b, ankle_b;

  double TorsoDistance(const Vector3d& q) const {
    const double z = std::clamp(q.z(), torso_bottom, torso_top);
    const Vector2d local(q.x(), q.y() - section_c(z));
    double d = EllipseDistance(local, section_a(z), section_b(z));
    // Closed below at the crotch, and above along the shoulder line: the trapezius slopes
    // from the neck's base down to the acromia.
    const double rel = std::min(std::abs(q.x()) / shoulder_half, 1.2);
    const double top =
        neck_base - (neck_base - (Proportions::kAcromion * H - 12)) * std::pow(rel, 1.7);
    d = SmoothMax(d, torso_bottom - q.z(), 0.02 * H);
    d = SmoothMax(d, q.z() - top, 0.05 * H);
    return d;
  }

  // The field in the body's upright, unturned frame, with the lean and the head's turn
  // undone per segment. The trunk (with the head) blends with each limb, the limbs not with
  // each other: min over limbs of smooth-min(trunk, limb), so the thighs never fill the
  // crotch and an arm never webs to a leg.
  // `part`, if given, gets which of trunk (-1, with neck and head) or limb 0..3 (left arm,
  // right arm, left leg, right leg) is nearest at this point, before blending.
  double Field(const Vector3d& world, unsigned groups, int* part = nullptr) const {
    const Vector3d body = body_from_world * world;
    const Vector3d upright = unlean * body;
    const Vector3d head_frame = unturn * upright;
    const double inf = std::numeric_limits<double>::infinity();
    double trunk = (groups & kTrunk) ? TorsoDistance(upright) : inf;
    std::array<double, 4> limb = {inf, inf, inf, inf};
    std::array<double, 4> limb_blend = {0, 0, 0, 0};
    for (const Primitive& prim : primitives) {
      if (!(prim.group & groups)) continue;
      const Vector3d& q = prim.segment == 1 ? body : prim.segment == 2 ? head_frame : upright;
      const int slot = prim.group == kLeftArm    ? 0
                       : prim.group == kRightArm ? 1
                       : prim.group == kLeftLeg  ? 2
                       : prim.group == kRightLeg ? 3
                                                 : -1;
      double& f = slot < 0 ? trunk : limb[slot];
      const double bound = (q - prim.bound_center).norm() - prim.bound_radius;
      if (prim.carve) {
        if (bound > prim.blend_mm) continue;
        f = SmoothMax(f, -prim.Distance(q), prim.blend_mm);
        continue;
      }
      if (bound > f + prim.blend_mm) continue;
      // A limb's first primitive is where it joins the trunk: its blend is the joint's.
      if (slot >= 0 && limb_blend[slot] == 0) {
        limb_blend[slot] = prim.blend_mm;
        f = prim.Distance(q);
        continue;
      }
      f = SmoothMin(f, prim.Distance(q), prim.blend_mm);
    }
    double result = trunk;
    bool any_limb = false;
    double joined = inf;
    for (int i = 0; i < 4; ++i) {
      if (limb[i] == inf) continue;
      any_limb = true;
      joined = std::min(joined, SmoothMin(trunk, limb[i], limb_blend[i]));
    }
    if (any_limb) result = std::min(result, joined);
    if (part) {
      *part = -1;
      double nearest = trunk;
      for (int i = 0; i < 4; ++i) {
        if (limb[i] < nearest) nearest = limb[i], *part = i;
      }
    }
    return std::max(result, -world.z());  // the soles stand on the floor
  }

  void Build();
  void PlaceStations();
  void PlacePrimitives();
  void Solve(int rounds);
  void PlaceLandmarks();
  double OutlinePerimeter(const Vector3d& origin, const Vector3d& e1, const Vector3d& e2,
                          double reach, unsigned groups) const;
  Vector3d SurfaceAlong(const Vector3d& from, const Vector3d& direction, double reach) const;
};

namespace {

// Perimeter of the convex hull of 2D points (a tape's girth around the outline).
double HullPerimeter(std::vector<Vector2d> points) {
  std::sort(points.begin(), points.end(), [](const Vector2d& a, const Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Vector2d& o, const Vector2d& a, const Vector2d& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<Vector2d> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  double perimeter = 0;
  for (size_t i = 0; i < hull.size(); ++i)
    perimeter += (hull[(i + 1) % hull.size()] - hull[i]).norm();
  return perimeter;
}

// The root of g (increasing in s) near s0, by the secant method; g(s) = 0 within 0.01.
template <typename G>
double SolveScale(const char* what, G g, double s0) {
  double s_prev = s0, g_prev = g(s0);
  double s = s0 * (g_prev > 0 ? 0.97 : 1.03);
  for (int i = 0; i < 30; ++i) {
    const double gs = g(s);
    if (std::abs(gs) < 0.01) return s;
    const double slope = (gs - g_prev) / (s - s_prev);
    if (std::abs(slope) < 1e-9)
      throw std::invalid_argument(std::string(what) +
                                  ": the body's other parts cover this section; cannot size it");
    s_prev = s;
    g_prev = gs;
    s = slope > 0 ? s - gs / slope : s * (gs > 0 ? 0.95 : 1.05);
    s = std::clamp(s, 0.3 * s0, 3.0 * s0);
  }
  throw std::invalid_argument(std::string(what) + ": cannot be met with the other girths");
}

}  // namespace

// The outline's perimeter in the plane (origin, e1, e2; upright body frame): on 360 rays from the
// origin (inside), where each first leaves the surface within `reach`, and the convex hull of those
// points (a tape).
double BodyField::Impl::OutlinePerimeter(const Vector3d& origin, const Vector3d& e1,
                                         const Vector3d& e2, double reach, unsigned groups) const {
  // The stations are in the upright body frame; the field is in world.
  const Eigen::Affine3d world_from_upright = world_from_body * lean;
  const Vector3d origin_w = world_from_upright * origin;
  const Vector3d e1_w = world_from_upright.linear() * e1, e2_w = world_from_upright.linear() * e2;
  std::vector<Vector2d> outline;
  constexpr int kRays = 360;
  for (int i = 0; i < kRays; ++i) {
    const double phi = 2 * kPi * i / kRays;
    const Vector2d dir(std::cos(phi), std::sin(phi));
    auto at = [&](double r) {
      return Field(origin_w + r * (dir.x() * e1_w + dir.y() * e2_w), groups);
    };
    double lo = 0, hi = -1;
    for (double r = 2.0; r <= reach; r += 2.0) {
      if (at(r) >= 0) {
        hi = r;
        break;
      }
      lo = r;
    }
    if (hi < 0) continue;
    for (int k = 0; k < 40; ++k) {
      const double mid = 0.5 * (lo + hi);
      (at(mid) < 0 ? lo : hi) = mid;
    }
    outline.push_back(0.5 * (lo + hi) * dir);
  }
  if (outline.size() < 3) return 0;
  return HullPerimeter(outline);
}

// The last surface crossing from `from` (inside) along `direction` within `reach`.
Vector3d BodyField::Impl::SurfaceAlong(const Vector3d& from, const Vector3d& direction,
                                       double reach) const {
  const Vector3d u = direction.normalized();
  double lo = 0, hi = reach;
  for (double r = 0; r <= reach; r += 1.0) {
    if (Field(from + r * u, kAll) >= 0) {
      hi = r;
      break;
    }
    lo = r;
  }
  for (int k = 0; k < 50; ++k) {
    const double mid = 0.5 * (lo + hi);
    (Field(from + mid * u, kAll) < 0 ? lo : hi) = mid;
  }
  return from + 0.5 * (lo + hi) * u;
}

void BodyField::Impl::PlaceStations() {
  const bool female = p.sex == "female";
  const double s = H / 1750.0;
  // Base ellipse girths, scaled by the solver; width/depth ratios from ANSUR II's breadths
  // and depths at each height.
  auto half_axes = [](double girth, double ratio) {
    const double b = girth / (kPi * (1 + ratio));  // near enough before the solve
    return std::pair{ratio * b, b};
  };
  const double underbust = p.underbust_girth_mm;
  const auto [ac, bc] = half_axes(p.chest_girth_mm * chest_scale, female ? 1.42 : 1.36);
  const auto [au, bu] = half_axes(underbust * underbust_scale, female ? 1.32 : 1.34);
  const auto [aw, bw] = half_axes(p.waist_girth_mm * waist_scale, female ? 1.36 : 1.28);
  const auto [ah, bh] = half_axes(p.hip_girth_mm * hip_scale, female ? 1.40 : 1.34);
  shoulder_half = 0.5 * p.shoulder_breadth_mm;
  const double z_waist = Proportions::kWaist * H, z_ub = Proportions::kUnderbust * H;
  const double z_chest = Proportions::kChest * H, z_arm = Proportions::kArmpit * H;
  const double z_ac = Proportions::kAcromion * H;
  const double z_hip = crotch_z + 0.55 * (z_waist - crotch_z) * 0.5 + 0.02 * H;
  const double top_a = std::max(shoulder_half - 30 * s, 0.9 * ac);
  stations = {
      {crotch_z, 0.72 * ah, 0.80 * bh, 0.06 * bh},
      {z_hip, ah, bh, 0.06 * bh},
      {z_waist, aw, bw, 0.0},
      {z_ub, au, bu, 0.0},
      {z_chest, ac, bc, 0.0},
      {z_arm, 0.97 * ac, 0.93 * bc, 0.03 * bc},
      {z_ac - 30 * s, top_a, 0.64 * bc, 0.10 * bc},
      {z_ac + 120 * s, 0.8 * top_a, 0.55 * bc, 0.12 * bc},
  };
  std::vector<double> z, a, b, c;
  for (const Station& st : stations) {
    z.push_back(st.z);
    a.push_back(st.a);
    b.push_back(st.b);
    c.push_back(st.c);
  }
  section_a.Set(z, a);
  section_b.Set(z, b);
  section_c.Set(z, c);
  torso_bottom = crotch_z;
  torso_top = stations.back().z;
  neck_base = Proportions::kCervicale * H - 8 * s;
}

void BodyField::Impl::PlacePrimitives() {
  primitives.clear();
  const bool female = p.sex == "female";
  const double s = H / 1750.0;
  auto cone = [&](unsigned group, int segment, double blend, Vector3d a, Vector3d b, double ra,
                  double rb) {
    Primitive prim{Primitive::kCone, group, segment, blend};
    prim.a = a;
    prim.b = b;
    prim.ra = ra;
    prim.rb = rb;
    prim.ComputeBound();
    primitives.push_back(prim);
  };
  auto ellipsoid = [&](unsigned group, int segment, double blend, Vector3d center, Vector3d semi,
                       Matrix3d axes = Matrix3d::Identity()) {
    Primitive prim{Primitive::kEllipsoid, group, segment, blend};
    prim.a = center;
    prim.semi = semi;
    prim.axes = axes;
    prim.ComputeBound();
    primitives.push_back(prim);
  };
  auto frame_along = [](const Vector3d& axis, const Vector3d& hint) {
    const Vector3d z = axis.normalized();
    const Vector3d x = (hint - hint.dot(z) * z).normalized();
    Matrix3d m;
    m << x, z.cross(x), z;
    return m;
  };

  const Station& chest = stations[4];
  const Station& waist = stations[2];
  const Station& hip = stations[1];
  // Bust or pectorals, on the chest's front at the bust points.
  for (int side : {-1, 1}) {
    const double x = side * (female ? 0.48 : 0.50) * chest.a;
    const double front = chest.c - chest.b * std::sqrt(std::max(0.0, 1 - 0.23 * 0.23 * 4));
    if (female) {
      // Centred at the bust point; the breast's lower pole sits just above the underbust
      // (the inframammary fold).
      const double size = (0.040 + 0.025 * p.bust) * H * std::sqrt(chest.a / (120 * s));
      const double semi_z = chest.z - stations[3].z - 6 * s;
      ellipsoid(kTrunk, 0, 0.02 * H, {x, front + size * (0.35 - 0.25 * p.bust), chest.z},
                {size * 0.72, size * (0.55 + 0.35 * p.bust), semi_z});
    } else {
      ellipsoid(kTrunk, 0, 0.02 * H, {x * 0.95, front + 0.28 * chest.b, chest.z + 0.03 * H},
                {0.40 * chest.a, 0.30 * chest.b, 0.05 * H});
    }
  }
  // Belly, in front of and below the waist.
  ellipsoid(kTrunk, 0, 0.03 * H,
            {0, waist.c - waist.b * (0.25 + 0.15 * p.belly), waist.z - 0.025 * H},
            {0.78 * waist.a, waist.b * (0.72 + 0.28 * p.belly), 0.075 * H});
  // Buttocks.
  for (int side : {-1, 1})
    ellipsoid(kTrunk, 0, 0.025 * H, {side * 0.42 * hip.a, hip.c + 0.42 * hip.b, hip.z - 0.012 * H},
              {0.52 * hip.a, 0.55 * hip.b, 0.062 * H});
  // Shoulder blades on the back, and the spine's hollow between them.
  const Station& armpit = stations[5];
  for (int side : {-1, 1})
    ellipsoid(kTrunk, 0, 0.03 * H,
              {side * 0.36 * armpit.a, armpit.c + 0.72 * armpit.b, armpit.z - 0.01 * H},
              {0.30 * armpit.a, 0.32 * armpit.b, 0.06 * H});
  {
    Primitive groove{Primitive::kCone, kTrunk, 0, 0.008 * H};
    groove.carve = true;
    groove.a = {0, waist.c + waist.b + 0.0042 * H, waist.z - 0.02 * H};
    groove.b = {0, armpit.c + armpit.b * 1.02 + 0.0042 * H, armpit.z};
    groove.ra = groove.rb = 0.005 * H;
    groove.ComputeBound();
    primitives.push_back(groove);
  }

  // Neck and head. The head's top is the stature.
  const double neck_r = neck_scale * p.neck_girth_mm / (2 * kPi);
  const Vector3d neck_low(0, 0.15 * chest.b, neck_base - 0.03 * H);
  const Vector3d neck_high(0, 0.05 * chest.b, Proportions::kChin * H + 0.01 * H);
  cone(kHead, 0, 0.02 * H, neck_low, neck_high, neck_r * 1.08, neck_r);
  head_semi = Vector3d(0.5 * Proportions::kHeadBreadth, 0.5 * Proportions::kHeadLength, 0.060) * H;
  head_center = Vector3d(0, neck_high.y() - 0.01 * H, H - head_semi.z());
  ellipsoid(kHead, 2, 0.02 * H, head_center, head_semi);
  const Vector3d jaw(0, head_center.y() - 0.50 * head_semi.y(), 0.895 * H);
  ellipsoid(kHead, 2, 0.008 * H, jaw,
            Vector3d(0.62 * head_semi.x(), 0.45 * head_semi.y(), 0.025 * H));
  const double eye_z = head_center.z() - 0.05 * head_semi.z();
  ellipsoid(kHead, 2, 0.004 * H, {0, head_center.y() - 0.93 * head_semi.y(), eye_z - 0.012 * H},
            {0.0065 * H, 0.010 * H, 0.017 * H});  // nose
  ellipsoid(kHead, 2, 0.006 * H,
            {0, jaw.y() - 0.36 * head_semi.y(), jaw.z() - 0.25 * head_semi.z()},
            {0.012 * H, 0.009 * H, 0.010 * H});  // chin
  for (int side : {-1, 1})
    ellipsoid(
        kHead, 2, 0.003 * H,
        {side * 0.97 * head_semi.x(), head_center.y() + 0.05 * head_semi.y(), eye_z - 0.01 * H},
        {0.006 * H, 0.013 * H, 0.019 * H});  // ears

  // Arms: the shoulder joint under the acromion, abducted in the frontal plane.
  const double alpha = Radians(p.arm_abduction_deg);
  const double bend = Radians(p.elbow_bend_deg);
  const double upper_len = Proportions::kUpperArm * H, fore_len = Proportions::kForearm * H;
  const double r_ua = arm_scale * p.upper_arm_girth_mm / (2 * kPi);
  for (int side : {-1, 1}) {
    const unsigned group = side > 0 ? kLeftArm : kRightArm;
    const int i = side > 0 ? 0 : 1;
    // A heavy body's chest is wider than its shoulders' skeleton: the arm hangs outside it.
    const Vector3d joint(side * std::max(shoulder_half, 0.9 * chest.a), 0.1 * chest.b,
                         Proportions::kAcromion * H - 0.026 * H);
    const Vector3d down(side * std::sin(alpha), 0, -std::cos(alpha));
    const Vector3d elbow = joint + upper_len * down;
    const Vector3d fore_dir = (std::cos(bend) * down + std::sin(bend) * Vector3d(0, -1, 0));
    const Vector3d wrist = elbow + fore_len * fore_dir;
    shoulder_b[i] = joint;
    elbow_b[i] = elbow;
    wrist_b[i] = wrist;
    // Trapezius and clavicle: neck base to shoulder.
    cone(group, 0, 0.012 * H, {side * 0.03 * H, 0.12 * chest.b, neck_base - 0.038 * H},
         joint + Vector3d(-side * 0.01 * H, 0, 0.0), 0.034 * H, 0.028 * H);
    ellipsoid(group, 0, 0.02 * H, joint + Vector3d(side * 0.004 * H, 0, -0.006 * H),
              Vector3d(0.030, 0.033, 0.036) * H * std::max(1.0, r_ua / (0.028 * H)),
              frame_along(down, Vector3d(side, 0, 0)));  // deltoid
    cone(group, 0, 0.025 * H, joint, elbow, r_ua * 1.02, 0.70 * r_ua);
    cone(group, 0, 0.015 * H, elbow, wrist, 0.74 * r_ua, 0.5 * r_ua);
    ellipsoid(group, 0, 0.015 * H, elbow + 0.3 * fore_len * fore_dir,
              Vector3d(0.80, 0.72, 2.2) * 0.5 * r_ua * 1.6,
              frame_along(fore_dir, Vector3d(side, 0, 0)));  // forearm muscles
    const Matrix3d hand_axes = frame_along(fore_dir, Vector3d(0, -1, 0));
    if (p.hands == "fist") {
      ellipsoid(group, 0, 0.008 * H, wrist + 0.045 * H * fore_dir,
                Vector3d(0.025, 0.0155, 0.040) * H, hand_axes);
      cone(group, 0, 0.006 * H, wrist + 0.01 * H * fore_dir + hand_axes.col(0) * 0.018 * H,
           wrist + 0.055 * H * fore_dir + hand_axes.col(0) * 0.022 * H -
               hand_axes.col(1) * side * 0.01 * H,
           0.0085 * H, 0.0075 * H);  // thumb along the fist
    } else {
      ellipsoid(group, 0, 0.008 * H, wrist + 0.03 * H * fore_dir, Vector3d(0.013, 0.027, 0.035) * H,
                hand_axes * Eigen::AngleAxisd(kPi / 2, Vector3d::UnitZ()).toRotationMatrix());
      for (int f = 0; f < 4; ++f) {
        const double across = (f - 1.5) * 0.011 * H;
        const Vector3d base = wrist + 0.058 * H * fore_dir + hand_axes.col(1) * across;
        const double len = (f == 1 || f == 2 ? 0.048 : 0.040) * H;
        cone(group, 0, 0.002 * H, base, base + len * fore_dir, 0.0052 * H, 0.0043 * H);
      }
      cone(group, 0, 0.003 * H, wrist + 0.02 * H * fore_dir + hand_axes.col(0) * 0.008 * H,
           wrist + 0.06 * H * fore_dir + hand_axes.col(0) * 0.02 * H, 0.0065 * H, 0.005 * H);
    }
  }

  // Legs: hip joints, knees on the hip-ankle line, feet on the floor (not leaning).
  const double thigh_r = thigh_scale * p.thigh_girth_mm / (2 * kPi);
  const double z_ankle = Proportions::kAnkle * H, z_knee = Proportions::kKnee * H;
  const double z_hipjoint = crotch_z + Proportions::kHipJointAboveCrotch * H;
  for (int side : {-1, 1}) {
    const unsigned group = side > 0 ? kLeftLeg : kRightLeg;
    const int i = side > 0 ? 0 : 1;
    const Vector3d hipj(side * hip_joint_x, 0.02 * H, z_hipjoint);
    const Vector3d ankle(side * ankle_x, 0.01 * H, z_ankle);
    const double t_knee = (z_hipjoint - z_knee) / (z_hipjoint - z_ankle);
    const Vector3d knee = hipj + t_knee * (ankle - hipj);
    hip_b[i] = hipj;
    knee_b[i] = knee;
    ankle_b[i] = ankle;
    const double knee_r = 0.034 * H * std::sqrt(thigh_r / (0.055 * H));
    // The thigh is fullest just below the gluteal fold and blends up into the pelvis.
    const double top_z = crotch_z - 50 * s + 0.3 * thigh_r;
    const Vector3d thigh_top = hipj + (z_hipjoint - top_z) / (z_hipjoint - z_knee) * (knee - hipj);
    cone(group, 0, 0.035 * H, thigh_top, knee, thigh_r * 1.04, knee_r * 0.92);
    ellipsoid(group, 0, 0.012 * H, knee + Vector3d(0, -0.55 * knee_r, 0.01 * H),
              Vector3d(0.55, 0.35, 0.6) * knee_r);  // kneecap
    const double ankle_r = 0.40 * knee_r + 0.008 * H;
    cone(group, 0, 0.02 * H, knee, ankle, knee_r * 0.85, ankle_r);
    ellipsoid(group, 0, 0.03 * H, knee + 0.30 * (ankle - knee) + Vector3d(0, 0.25 * knee_r, 0),
              Vector3d(0.85 * knee_r, 0.85 * knee_r, 0.11 * H));  // calf
    // Foot (segment 1: stays flat on the floor when the body leans), turned out 8 degrees.
    const double foot_len = Proportions::kFootLength * H, foot_w = Proportions::kFootBreadth * H;
    const Matrix3d out = Eigen::AngleAxisd(side * Radians(8), Vector3d::UnitZ()).toRotationMatrix();
    const Vector3d heel = ankle + Vector3d(0, 0.17 * foot_len, 0);
    ellipsoid(group, 1, 0.01 * H, Vector3d(heel.x(), heel.y(), 0.012 * H),
              {0.40 * foot_w, 0.18 * foot_len, 0.030 * H}, out);  // heel
    ellipsoid(group, 1, 0.02 * H,
              Vector3d(ankle.x(), ankle.y(), 0) + out * Vector3d(0, -0.27 * foot_len, 0.012 * H),
              {0.52 * foot_w, 0.50 * foot_len, 0.038 * H}, out);  // instep to toes
    cone(group, 1, 0.015 * H, ankle + Vector3d(0, 0, 0.01 * H),
         Vector3d(ankle.x(), ankle.y(), 0) + out * Vector3d(0, -0.30 * foot_len, 0.025 * H),
         ankle_r * 1.05, 0.018 * H);
  }
}

void BodyField::Impl::Build() {
  PlaceStations();
  PlacePrimitives();
}

void BodyField::Impl::Solve(int rounds) {
  const double s = H / 1750.0;
  const Vector3d ex = Vector3d::UnitX(), ey = Vector3d::UnitY();
  // The thigh's girth just below the crotch, then the torso's stations (their sections
  // include what the legs add at the hip), then the arm and the neck; twice round, as
  // each moves the others a little.
  for (int round = 0; round < rounds; ++round) {
    const double thigh_z = crotch_z - 50 * s;
    thigh_scale = SolveScale(
        "thigh_girth_mm",
        [&](double scale) {
          thigh_scale = scale;
          Build();
          const double t =
              (crotch_z + Proportions::kHipJointAboveCrotch * H - thigh_z) /
              (crotch_z + Proportions::kHipJointAboveCrotch * H - Proportions::kAnkle * H);
          const double x = hip_joint_x + t * (ankle_x - hip_joint_x);
          return OutlinePerimeter(Vector3d(x, 0.02 * H, thigh_z), ex, ey, p.thigh_girth_mm / 2,
                                  kAll) -
                 p.thigh_girth_mm;
        },
        thigh_scale);
    struct Target {
      const char* name;
      double* scale;
      int station;
      double girth;
    };
    for (const Target& target :
         {Target{"hip_girth_mm", &hip_scale, 1, p.hip_girth_mm},
          Target{"waist_girth_mm", &waist_scale, 2, p.waist_girth_mm},
          Target{"underbust_girth_mm", &underbust_scale, 3, p.underbust_girth_mm},
          Target{"chest_girth_mm", &chest_scale, 4, p.chest_girth_mm}}) {
      // Arms held close may touch the torso at the station; then the girth is the
      // torso's alone (the truth withholds a merged section).
      for (const unsigned groups : {unsigned{kAll}, unsigned{kAll & ~(kLeftArm | kRightArm)}}) {
        try {
          *target.scale = SolveScale(
              target.name,
              [&](double scale) {
                *target.scale = scale;
                Build();
                const double z = stations[target.station].z;
                return OutlinePerimeter(Vector3d(0, section_c(z), z), ex, ey, 0.5 * target.girth,
                                        groups) -
                       target.girth;
              },
              *target.scale);
          break;
        } catch (const std::invalid_argument&) {
          if (groups != kAll) throw;
          *target.scale = 1.0;
        }
      }
    }
    arm_scale = SolveScale(
        "upper_arm_girth_mm",
        [&](double scale) {
          arm_scale = scale;
          Build();
          // Midway between the acromion and the olecranon along the arm, as the truth
          // takes it (body_truth.cc).
          PlaceLandmarks();
          const Vector3d axis = (elbow_b[0] - shoulder_b[0]).normalized();
          const Eigen::Affine3d upright_from_world = (world_from_body * lean).inverse();
          const double t =
              0.5 * ((upright_from_world * marks.acromion[0] - shoulder_b[0]).dot(axis) +
                     (upright_from_world * marks.elbow[0] - shoulder_b[0]).dot(axis));
          const Vector3d mid = shoulder_b[0] + t * axis;
          const Vector3d e1 = ey.cross(axis).normalized();
          return OutlinePerimeter(mid, e1, axis.cross(e1), 0.5 * p.upper_arm_girth_mm, kAll) -
                 p.upper_arm_girth_mm;
        },
        arm_scale);
    neck_scale = SolveScale(
        "neck_girth_mm",
        [&](double scale) {
          neck_scale = scale;
          Build();
          const double z = Proportions::kNeckGirth * H;
          return OutlinePerimeter(Vector3d(0, 0.1 * stations[4].b, z), ex, ey,
                                  0.45 * p.neck_girth_mm, kAll) -
                 p.neck_girth_mm;
        },
        neck_scale);
  }
}

void BodyField::Impl::PlaceLandmarks() {
  const double s = H / 1750.0;
  auto surface_up = [&](const Vector3d& inside_upright, const Vector3d& dir) {
    return SurfaceAlong(world_from_body * (lean * inside_upright),
                        world_from_body.linear() * (lean.linear() * dir), 400 * s);
  };
  const Vector3d up = Vector3d::UnitZ();
  marks.vertex = SurfaceAlong(world_from_body * (lean * (unturn.inverse() * head_center)),
                              world_from_body.linear() * (lean.linear() * up), 300 * s);
  const double z_cerv = Proportions::kCervicale * H;
  marks.cervicale = surface_up(Vector3d(0, section_c(z_cerv), z_cerv), Vector3d::UnitY());
  for (int i = 0; i < 2; ++i) {
    const double side = i == 0 ? 1 : -1;
    marks.acromion[i] = surface_up(
        Vector3d(side * shoulder_half, 0.1 * stations[4].b, Proportions::kAcromion * H - 0.05 * H),
        up);
    {
      // Down onto the shoulder just beside the neck: where the neck's base meets the
      // shoulder line.
      const Vector3d above =
          world_from_body * (lean * Vector3d(side * 1.1 * p.neck_girth_mm / (2 * kPi),
                                             0.1 * stations[4].b, neck_base + 0.05 * H));
      const Vector3d down = world_from_body.linear() * (lean.linear() * -up);
      double lo = 0, hi = 0.15 * H;
      for (double r = 0; r <= 0.15 * H; r += 0.5) {
        if (Field(above + r * down, kAll) < 0) {
          hi = r;
          break;
        }
        lo = r;
      }
      for (int k = 0; k < 50; ++k) {
        const double mid = 0.5 * (lo + hi);
        (Field(above + mid * down, kAll) < 0 ? hi : lo) = mid;
      }
      marks.side_neck[i] = above + 0.5 * (lo + hi) * down;
    }
    const Vector3d fore_dir = (wrist_b[i] - elbow_b[i]).normalized();
    const Vector3d back_of_elbow = Vector3d(0, 1, 0) - fore_dir * fore_dir.y();
    marks.elbow[i] = surface_up(elbow_b[i], back_of_elbow);
    const Vector3d outward = Vector3d(side, 0, 0) - fore_dir * fore_dir.x() * side;
    marks.wrist[i] = surface_up(wrist_b[i], outward);
  }
  // The crotch: up from the floor between the legs to the first surface.
  {
    const Vector3d start = world_from_body * (lean * Vector3d(0, 0.02 * H, 1.0));
    const Vector3d dir = world_from_body.linear() * (lean.linear() * up);
    double lo = 0, hi = 0.7 * H;
    for (double r = 0; r <= 0.7 * H; r += 1.0) {
      if (Field(start + r * dir, kAll) < 0) {
        hi = r;
        break;
      }
      lo = r;
    }
    for (int k = 0; k < 50; ++k) {
      const double mid = 0.5 * (lo + hi);
      (Field(start + mid * dir, kAll) < 0 ? hi : lo) = mid;
    }
    marks.crotch = start + 0.5 * (lo + hi) * dir;
  }
  // The world frame's stations and axes.
  for (int i = 0; i < 2; ++i) {
    marks.shoulder_joint[i] = world_from_body * (lean * shoulder_b[i]);
    marks.elbow_joint[i] = world_from_body * (lean * elbow_b[i]);
    marks.wrist_joint[i] = world_from_body * (lean * wrist_b[i]);
    marks.hip_joint[i] = world_from_body * (lean * hip_b[i]);
    marks.knee_joint[i] = world_from_body * (lean * knee_b[i]);
    marks.ankle_joint[i] = world_from_body * ankle_b[i];
  }
  marks.chest_z = stations[4].z;
  marks.underbust_z = stations[3].z;
  marks.waist_z = stations[2].z;
  marks.hip_z = stations[1].z;
  marks.thigh_z = crotch_z - 50 * s;
  marks.knee_z = Proportions::kKnee * H;
  marks.neck_z = Proportions::kNeckGirth * H;
  marks.back_width_z = stations[4].z + 0.3 * (stations[5].z - stations[4].z);
  marks.up = world_from_body.linear() * (lean.linear() * up);
  marks.forward = world_from_body.linear() * (lean.linear() * -Vector3d::UnitY());
  marks.left = world_from_body.linear() * (lean.linear() * Vector3d::UnitX());
  marks.ankle_center = world_from_body * Vector3d(0, 0.01 * H, Proportions::kAnkle * H);
  marks.world_from_upright = world_from_body * lean;
}

BodyField::BodyField(const BodyParams& params) : impl_(std::make_unique<Impl>()) {
  params.Validate();
  Impl& m = *impl_;
  m.p = params;
  BodyParams& p = m.p;
  m.H = p.stature_mm;
  const bool female = p.sex == "female";
  if (p.underbust_girth_mm <= 0) p.underbust_girth_mm = p.chest_girth_mm * (female ? 0.84 : 0.93);
  if (p.neck_girth_mm <= 0)
    p.neck_girth_mm = (female ? 0.335 : 0.385) * p.chest_girth_mm + (female ? 10 : 20);
  if (p.shoulder_breadth_mm <= 0) p.shoulder_breadth_mm = (female ? 0.222 : 0.230) * m.H;
  if (p.leg_length_mm <= 0) p.leg_length_mm = 0.472 * m.H;
  m.crotch_z = p.leg_length_mm;
  // Hip joints under the hip's breadth; the feet apart as asked, else at hip width but
  // keeping the thighs 24 mm apart at their girth.
  const double thigh_r = p.thigh_girth_mm / (2 * kPi);
  const double hip_half = p.hip_girth_mm / (kPi * 2.35) * 1.35;
  m.hip_joint_x = std::max(0.48 * hip_half, thigh_r + 16);
  m.ankle_x = p.feet_apart_mm > 0 ? 0.5 * p.feet_apart_mm : m.hip_joint_x;
  m.world_from_body = Eigen::Translation3d(p.center_mm.x(), p.center_mm.y(), 0) *
                      Eigen::AngleAxisd(Radians(p.yaw_deg), Vector3d::UnitZ());
  m.body_from_world = m.world_from_body.inverse();
  const Vector3d ankle_pivot(0, 0.01 * m.H, Proportions::kAnkle * m.H);
  m.lean = Eigen::Translation3d(ankle_pivot) *
           Eigen::AngleAxisd(-Radians(p.lean_deg), Vector3d::UnitX()) *
           Eigen::Translation3d(-ankle_pivot);
  m.unlean = m.lean.inverse();
  m.head_turn = Eigen::AngleAxisd(Radians(p.head_turn_deg), Vector3d::UnitZ());
  m.unturn = m.head_turn.inverse();
  // Head turn about the neck's axis (x = y = 0 in the upright frame is close enough).
  m.Solve(2);
  m.Build();
  // The crotch where the leg length puts it: the torso's bottom moved by the difference.
  for (int i = 0; i < 3; ++i) {
    m.PlaceLandmarks();
    const Vector3d crotch_body = m.unlean * (m.body_from_world * m.marks.crotch);
    const double error = crotch_body.z() - p.leg_length_mm;
    if (std::abs(error) < 0.05) break;
    m.crotch_z -= error;
    m.Solve(1);
    m.Build();
  }
  m.PlaceLandmarks();
}

BodyField::~BodyField() = default;
BodyField::BodyField(BodyField&&) noexcept = default;

double BodyField::Evaluate(const Vector3d& point_in_world) const {
  return impl_->Field(point_in_world, kAll);
}

BodyPart BodyField::PartAt(const Vector3d& point_in_world) const {
  int part = -1;
  impl_->Field(point_in_world, kAll, &part);
  return static_cast<BodyPart>(part + 1);
}

const char* BodyField::RegionAt(const Vector3d& point_in_world) const {
  const Impl& m = *impl_;
  const Vector3d upright = m.unlean * (m.body_from_world * point_in_world);
  const Vector3d head = m.unturn * upright;
  const double H = m.H;
  // Hair: the head's crown and back, above the ears and behind the face.
  const Vector3d h = head - m.head_center;
  if (h.z() > -0.1 * m.head_semi.z() && h.norm() < 1.4 * m.head_semi.maxCoeff()) {
    const bool face = h.y() < -0.45 * m.head_semi.y() && h.z() < 0.45 * m.head_semi.z();
    if (!face && (h.z() > 0.25 * m.head_semi.z() || h.y() > -0.1 * m.head_semi.y())) return "hair";
  }
  // Underwear: briefs from the crotch to between hip and waist, on the trunk and the
  // thighs' tops; a bra band around the bust for a woman.
  const double z = upright.z();
  const bool near_trunk = std::abs(upright.x()) < 0.5 * m.p.hip_girth_mm / kPi * 1.3;
  if (near_trunk && z > m.crotch_z - 0.03 * H &&
      z < m.stations[1].z + 0.3 * (m.stations[2].z - m.stations[1].z))
    return "underwear";
  if (m.p.sex == "female" && std::abs(upright.x()) < m.stations[4].a * 1.1) {
    const bool back = upright.y() > m.section_c(z);
    const double lo = m.stations[3].z - 0.012 * H;
    const double hi = back ? m.stations[3].z + 0.02 * H : m.stations[4].z + 0.035 * H;
    if (z > lo && z < hi) return "underwear";
  }
  return "skin";
}

Eigen::AlignedBox3d BodyField::Bounds() const {
  const Impl& m = *impl_;
  Eigen::AlignedBox3d box;
  for (const Primitive& prim : m.primitives) {
    const Vector3d c =
        prim.segment == 1
            ? prim.bound_center
            : Vector3d(m.lean * (prim.segment == 2 ? Vector3d(m.head_turn * prim.bound_center)
                                                   : prim.bound_center));
    const Vector3d w = m.world_from_body * c;
    box.extend(w + Vector3d::Constant(prim.bound_radius + 5));
    box.extend(w - Vector3d::Constant(prim.bound_radius + 5));
  }
  const double r = 0.6 * m.p.hip_girth_mm / kPi + 0.6 * m.p.chest_girth_mm / kPi;
  for (double z : {m.torso_bottom, m.torso_top}) {
    box.extend(m.world_from_body * (m.lean * Vector3d(r, r, z)));
    box.extend(m.world_from_body * (m.lean * Vector3d(-r, -r, z)));
  }
  box.min().z() = -5.0;
  return box;
}

const BodyLandmarks& BodyField::landmarks() const { return impl_->marks; }
const BodyParams& BodyField::params() const { return impl_->p; }

nlohmann::json BodyField::SolvedFigures() const {
  const Impl& m = *impl_;
  return {{"stature_mm", m.head_center.z() + m.head_semi.z()},
          {"scales",
           {{"chest", m.chest_scale},
            {"underbust", m.underbust_scale},
            {"waist", m.waist_scale},
            {"hip", m.hip_scale},
            {"thigh", m.thigh_scale},
            {"upper_arm", m.arm_scale},
            {"neck", m.neck_scale}}}};
}

void BodyParams::Validate() const {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument(what);
  };
  require(sex == "male" || sex == "female", "sex: must be \"male\" or \"female\"");
  require(stature_mm >= 1300 && stature_mm <= 2200, "stature_mm: must be in [1300, 2200]");
  require(chest_girth_mm >= 0.4 * stature_mm && chest_girth_mm <= 0.95 * stature_mm,
          "chest_girth_mm: must be 0.40-0.95 x stature_mm");
  require(waist_girth_mm >= 0.33 * stature_mm && waist_girth_mm <= 0.95 * stature_mm,
          "waist_girth_mm: must be 0.33-0.95 x stature_mm");
  require(hip_girth_mm >= 0.42 * stature_mm && hip_girth_mm <= 0.95 * stature_mm,
          "hip_girth_mm: must be 0.42-0.95 x stature_mm");
  require(underbust_girth_mm == 0 ||
              (underbust_girth_mm > 0.5 * chest_girth_mm && underbust_girth_mm <= chest_girth_mm),
          "underbust_girth_mm: must be 0 (derived) or 0.5-1 x chest_girth_mm");
  require(thigh_girth_mm >= 0.22 * stature_mm && thigh_girth_mm <= 0.50 * stature_mm,
          "thigh_girth_mm: must be 0.22-0.50 x stature_mm");
  require(upper_arm_girth_mm >= 0.12 * stature_mm && upper_arm_girth_mm <= 0.30 * stature_mm,
          "upper_arm_girth_mm: must be 0.12-0.30 x stature_mm");
  require(neck_girth_mm == 0 || (neck_girth_mm >= 250 && neck_girth_mm <= 550),
          "neck_girth_mm: must be 0 (derived) or 250-550");
  require(shoulder_breadth_mm == 0 || (shoulder_breadth_mm >= 0.18 * stature_mm &&
                                       shoulder_breadth_mm <= 0.28 * stature_mm),
          "shoulder_breadth_mm: must be 0 (derived) or 0.18-0.28 x stature_mm");
  require(leg_length_mm == 0 ||
              (leg_length_mm >= 0.42 * stature_mm && leg_length_mm <= 0.52 * stature_mm),
          "leg_length_mm: must be 0 (derived) or 0.42-0.52 x stature_mm");
  require(belly >= 0 && belly <= 1, "belly: must be in [0, 1]");
  require(bust >= 0 && bust <= 1, "bust: must be in [0, 1]");
  require(arm_abduction_deg >= 0 && arm_abduction_deg <= 60,
          "arm_abduction_deg: must be in [0, 60]");
  require(elbow_bend_deg >= 0 && elbow_bend_deg <= 90, "elbow_bend_deg: must be in [0, 90]");
  require(feet_apart_mm >= 0 && feet_apart_mm <= 0.45 * stature_mm,
          "feet_apart_mm: must be 0 (hip width) to 0.45 x stature_mm");
  require(std::abs(lean_deg) <= 10, "lean_deg: must be in [-10, 10]");
  require(std::abs(head_turn_deg) <= 60, "head_turn_deg: must be in [-60, 60]");
  require(hands == "fist" || hands == "open", "hands: must be \"fist\" or \"open\"");
  for (auto [value, key] :
       {std::pair{skin_albedo, "skin_albedo"}, std::pair{hair_albedo, "hair_albedo"},
        std::pair{underwear_albedo, "underwear_albedo"}})
    require(value > 0 && value <= 1, std::string(key) + ": must be in (0, 1]");
}

nlohmann::json BodyParams::ToJson() const {
  return {{"sex", sex},
          {"stature_mm", stature_mm},
          {"chest_girth_mm", chest_girth_mm},
          {"underbust_girth_mm", underbust_girth_mm},
          {"waist_girth_mm", waist_girth_mm},
          {"hip_girth_mm", hip_girth_mm},
          {"thigh_girth_mm", thigh_girth_mm},
          {"upper_arm_girth_mm", upper_arm_girth_mm},
          {"neck_girth_mm", neck_girth_mm},
          {"shoulder_breadth_mm", shoulder_breadth_mm},
          {"leg_length_mm", leg_length_mm},
          {"belly", belly},
          {"bust", bust},
          {"arm_abduction_deg", arm_abduction_deg},
          {"elbow_bend_deg", elbow_bend_deg},
          {"feet_apart_mm", feet_apart_mm},
          {"yaw_deg", yaw_deg},
          {"lean_deg", lean_deg},
          {"head_turn_deg", head_turn_deg},
          {"hands", hands},
          {"center_mm", {center_mm.x(), center_mm.y()}},
          {"skin_albedo", skin_albedo},
          {"hair_albedo", hair_albedo},
          {"underwear_albedo", underwear_albedo}};
}

nlohmann::json BodyLandmarks::ToJson() const {
  auto v = [](const Vector3d& x) { return nlohmann::json{x.x(), x.y(), x.z()}; };
  auto pair = [&](const std::array<Vector3d, 2>& x) { return nlohmann::json{v(x[0]), v(x[1])}; };
  return {{"vertex", v(vertex)},
          {"cervicale", v(cervicale)},
          {"acromion", pair(acromion)},
          {"side_neck", pair(side_neck)},
          {"elbow", pair(elbow)},
          {"wrist", pair(wrist)},
          {"crotch", v(crotch)},
          {"shoulder_joint", pair(shoulder_joint)},
          {"elbow_joint", pair(elbow_joint)},
          {"wrist_joint", pair(wrist_joint)},
          {"hip_joint", pair(hip_joint)},
          {"knee_joint", pair(knee_joint)},
          {"ankle_joint", pair(ankle_joint)},
          {"stations_z_mm",
           {{"chest", chest_z},
            {"underbust", underbust_z},
            {"waist", waist_z},
            {"hip", hip_z},
            {"thigh", thigh_z},
            {"knee", knee_z},
            {"neck", neck_z},
            {"back_width", back_width_z}}},
          {"up", v(up)},
          {"forward", v(forward)},
          {"left", v(left)},
          {"ankle_center", v(ankle_center)},
          {"world_from_upright", std::vector<double>(world_from_upright.matrix().data(),
                                                     world_from_upright.matrix().data() + 16)}};
}

BodyLandmarks BodyLandmarks::FromJson(const nlohmann::json& j) {
  auto v = [](const nlohmann::json& x) {
    return Vector3d(x.at(0).get<double>(), x.at(1).get<double>(), x.at(2).get<double>());
  };
  auto pair = [&](const nlohmann::json& x) {
    return std::array<Vector3d, 2>{v(x.at(0)), v(x.at(1))};
  };
  BodyLandmarks m;
  m.vertex = v(j.at("vertex"));
  m.cervicale = v(j.at("cervicale"));
  m.acromion = pair(j.at("acromion"));
  m.side_neck = pair(j.at("side_neck"));
  m.elbow = pair(j.at("elbow"));
  m.wrist = pair(j.at("wrist"));
  m.crotch = v(j.at("crotch"));
  m.shoulder_joint = pair(j.at("shoulder_joint"));
  m.elbow_joint = pair(j.at("elbow_joint"));
  m.wrist_joint = pair(j.at("wrist_joint"));
  m.hip_joint = pair(j.at("hip_joint"));
  m.knee_joint = pair(j.at("knee_joint"));
  m.ankle_joint = pair(j.at("ankle_joint"));
  const nlohmann::json& z = j.at("stations_z_mm");
  m.chest_z = z.at("chest");
  m.underbust_z = z.at("underbust");
  m.waist_z = z.at("waist");
  m.hip_z = z.at("hip");
  m.thigh_z = z.at("thigh");
  m.knee_z = z.at("knee");
  m.neck_z = z.at("neck");
  m.back_width_z = z.at("back_width");
  m.up = v(j.at("up"));
  m.forward = v(j.at("forward"));
  m.left = v(j.at("left"));
  m.ankle_center = v(j.at("ankle_center"));
  const std::vector<double> matrix = j.at("world_from_upright").get<std::vector<double>>();
  m.world_from_upright.matrix() = Eigen::Map<const Eigen::Matrix4d>(matrix.data());
  return m;
}

const char* BodyPartName(BodyPart part) {
  switch (part) {
    case BodyPart::kTrunk:
      return "trunk";
    case BodyPart::kLeftArm:
      return "left_arm";
    case BodyPart::kRightArm:
      return "right_arm";
    case BodyPart::kLeftLeg:
      return "left_leg";
    case BodyPart::kRightLeg:
      return "right_leg";
  }
  return "trunk";
}

Subject MakeBody(const BodyParams& params, double cell_mm) {
  const BodyField field(params);
  Subject subject;
  subject.type = "body";
  subject.mesh = MeshIsosurface([&field](const Vector3d& x) { return field.Evaluate(x); },
                                field.Bounds(), cell_mm, 3.0 * cell_mm * 4 * 0.87 + 10.0);
  // Triangles grouped by part (the metadata's "parts" ranges, for per-region figures),
  // each with its material's albedo.
  const size_t n = subject.mesh.triangles.size();
  std::vector<int> part_of(n), region_of(n);
  for (size_t t = 0; t < n; ++t) {
    const Eigen::Vector3i& tri = subject.mesh.triangles[t];
    const Vector3d centroid = (subject.mesh.vertices[tri[0]] + subject.mesh.vertices[tri[1]] +
                               subject.mesh.vertices[tri[2]]) /
                              3;
    part_of[t] = static_cast<int>(field.PartAt(centroid));
    const std::string region = field.RegionAt(centroid);
    region_of[t] = region == "hair" ? 1 : region == "underwear" ? 2 : 0;
  }
  std::vector<size_t> order(n);
  for (size_t t = 0; t < n; ++t) order[t] = t;
  std::stable_sort(order.begin(), order.end(),
                   [&part_of](size_t a, size_t b) { return part_of[a] < part_of[b]; });
  std::vector<Eigen::Vector3i> triangles(n);
  size_t counts[3] = {0, 0, 0};
  const BodyParams& p = field.params();
  subject.triangle_albedo.reserve(n);
  subject.metadata["parts"] = nlohmann::json::array();
  for (size_t i = 0; i < n; ++i) {
    const size_t t = order[i];
    triangles[i] = subject.mesh.triangles[t];
    const int r = region_of[t];
    ++counts[r];
    subject.triangle_albedo.push_back(static_cast<float>(r == 1   ? p.hair_albedo
                                                         : r == 2 ? p.underwear_albedo
                                                                  : p.skin_albedo));
    if (i == 0 || part_of[t] != part_of[order[i - 1]]) {
      subject.metadata["parts"].push_back(
          {{"name", BodyPartName(static_cast<BodyPart>(part_of[t]))},
           {"first_triangle", i},
           {"triangle_count", 0}});
    }
    subject.metadata["parts"].back()["triangle_count"] =
        subject.metadata["parts"].back()["triangle_count"].get<size_t>() + 1;
  }
  subject.mesh.triangles = std::move(triangles);
  subject.metadata["type"] = "body";
  subject.metadata["params"] = p.ToJson();
  subject.metadata["regions"] = {{"skin_triangles", counts[0]},
                                 {"hair_triangles", counts[1]},
                                 {"underwear_triangles", counts[2]}};
  subject.metadata["landmarks"] = field.landmarks().ToJson();
  subject.metadata["builder"] = field.SolvedFigures();
  subject.metadata["truth"] = BodyMeasurementTruth(subject.mesh, field.landmarks());
  subject.metadata["height_mm"] = p.stature_mm;
  return subject;
}

}  // namespace mirrorscan::virtual_cabinet

#include "host/pose/pose_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <unordered_map>
#include <utility>

#include <Eigen/Dense>

#include "host/measurement/head_cap.h"

namespace mirrorscan::pose {
namespace {

constexpr double kPi = 3.14159265358979323846;
double Degrees(double radians) { return radians * 180.0 / kPi; }

// Station heights as fractions of the stature (docs/pose-check.md): where the legs, the
// arms, the neck and the head are on any adult in the standard posture.
constexpr double kLegsFrom = 0.06, kLegsTo = 0.36, kLegsStep = 0.02;  // shins to thighs
constexpr double kAnklesTo = 0.10;  // the lowest leg stations give the feet spread
constexpr double kHipJoint = 0.51;  // the legs' spread extrapolated here (hip joints)
constexpr double kArmsFrom = 0.56, kArmsTo = 0.67;    // below the armpit, above the wrists
constexpr double kTrunkFrom = 0.55, kTrunkTo = 0.62;  // the trunk, for yaw without legs
constexpr double kNeckFrom = 0.87, kNeckTo = 0.90;    // jaw and neck, for the lean
constexpr double kHeadFrom = 0.90;                    // the head's sections, for its turn
constexpr double kAnkle = 0.04;                       // the lean's pivot height
constexpr double kCrotch = 0.47;      // crotch height, for the stature when the head is cut
constexpr double kFeetMargin = 0.03;  // how much further the toes reach than the heels

// The value below which a share q of the values lie (the nearest rank).
double Quantile(std::vector<double> values, double q) {
  const size_t at = std::min(values.size() - 1, static_cast<size_t>(q * values.size()));
  std::nth_element(values.begin(), values.begin() + at, values.end());
  return values[at];
}

double Median(std::vector<double> values) {
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  double median = values[mid];
  if (values.size() % 2 == 0) {
    median = 0.5 * (median + *std::max_element(values.begin(), values.begin() + mid));
  }
  return median;
}

// Union-find over indices.
class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void Join(size_t a, size_t b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<size_t> parent_;
};

int64_t CellKey(int64_t i, int64_t j, int64_t k = 0) {
  constexpr int64_t kOffset = 1 << 20;
  return ((i + kOffset) << 42) | ((j + kOffset) << 21) | (k + kOffset);
}

// The cloud without stray points: 20 mm voxels kept when their 3 x 3 x 3 neighbourhood
// holds at least 8 points, and of those only the 26-connected groups holding at least 1 %
// of the points (a stray stripe beside a shin is a group of its own; the body is one or a
// few groups split by holes).
std::vector<Eigen::Vector3d> WithoutStrays(const std::vector<Eigen::Vector3d>& points) {
  constexpr double kVoxel = 20.0;
  constexpr int kMinNeighbourhood = 8;
  std::unordered_map<int64_t, int> count;
  std::vector<int64_t> key(points.size());
  auto voxel = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / kVoxel)),
                           static_cast<int>(std::floor(p.y() / kVoxel)),
                           static_cast<int>(std::floor(p.z() / kVoxel)));
  };
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3i v = voxel(points[i]);
    key[i] = CellKey(v.x(), v.y(), v.z());
    ++count[key[i]];
  }
  std::unordered_map<int64_t, size_t> kept;  // voxel -> its index among the kept ones
  std::vector<Eigen::Vector3i> kept_voxels;
  for (size_t i = 0; i < points.size(); ++i) {
    if (count.at(key[i]) < 0) continue;  // decided already: kept (marked) or not
    const Eigen::Vector3i v = voxel(points[i]);
    int around = 0;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = count.find(CellKey(v.x() + dx, v.y() + dy, v.z() + dz));
          if (it != count.end()) around += std::abs(it->second);
        }
    if (around >= kMinNeighbourhood) {
      kept.emplace(key[i], kept_voxels.size());
      kept_voxels.push_back(v);
    }
    count[key[i]] = -count[key[i]];  // negative: decided; its magnitude still the count
  }
  DisjointSets groups(kept_voxels.size());
  for (size_t n = 0; n < kept_voxels.size(); ++n) {
    const Eigen::Vector3i& v = kept_voxels[n];
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = kept.find(CellKey(v.x() + dx, v.y() + dy, v.z() + dz));
          if (it != kept.end()) groups.Join(n, it->second);
        }
  }
  std::vector<size_t> group_points(kept_voxels.size(), 0);
  size_t total = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const auto it = kept.find(key[i]);
    if (it == kept.end()) continue;
    ++group_points[groups.Find(it->second)];
    ++total;
  }
  std::vector<Eigen::Vector3d> out;
  out.reserve(total);
  for (size_t i = 0; i < points.size(); ++i) {
    const auto it = kept.find(key[i]);
    if (it != kept.end() && group_points[groups.Find(it->second)] >= 0.01 * total) {
      out.push_back(points[i]);
    }
  }
  return out;
}

// A connected group of a section's points (2D), its size and extent.
struct Blob {
  std::vector<Eigen::Vector2d> points;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Vector2d min, max;
};

// The section's points in groups: 10 mm cells, cells up to two apart joined (so a ring
// with a hole stays one group, and two legs 30 mm apart are two), largest first.
std::vector<Blob> Blobs(const std::vector<Eigen::Vector2d>& points) {
  constexpr double kCell = 10.0;
  constexpr int kJoin = 2;
  std::unordered_map<int64_t, size_t> cells;
  std::vector<Eigen::Vector2i> cell_of;
  std::vector<size_t> index(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2i c(static_cast<int>(std::floor(points[i].x() / kCell)),
                            static_cast<int>(std::floor(points[i].y() / kCell)));
    const auto [it, added] = cells.emplace(CellKey(c.x(), c.y()), cell_of.size());
    if (added) cell_of.push_back(c);
    index[i] = it->second;
  }
  DisjointSets sets(cell_of.size());
  for (size_t n = 0; n < cell_of.size(); ++n) {
    for (int di = -kJoin; di <= kJoin; ++di)
      for (int dj = -kJoin; dj <= kJoin; ++dj) {
        const auto it = cells.find(CellKey(cell_of[n].x() + di, cell_of[n].y() + dj));
        if (it != cells.end()) sets.Join(n, it->second);
      }
  }
  std::unordered_map<size_t, size_t> blob_of;
  std::vector<Blob> blobs;
  for (size_t i = 0; i < points.size(); ++i) {
    const size_t root = sets.Find(index[i]);
    const auto [it, added] = blob_of.emplace(root, blobs.size());
    if (added) blobs.emplace_back();
    blobs[it->second].points.push_back(points[i]);
  }
  for (Blob& b : blobs) {
    b.min = b.max = b.points.front();
    for (const Eigen::Vector2d& p : b.points) {
      b.mean += p;
      b.min = b.min.cwiseMin(p);
      b.max = b.max.cwiseMax(p);
    }
    b.mean /= static_cast<double>(b.points.size());
  }
  std::sort(blobs.begin(), blobs.end(),
            [](const Blob& a, const Blob& b) { return a.points.size() > b.points.size(); });
  return blobs;
}

// The circle through a group's points (algebraic least squares): its centre stays on a
// limb's axis when only an arc of the limb is seen.
struct Circle {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double radius = 0.0;
};
std::optional<Circle> FitCircle(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 6) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  // x^2 + y^2 + D x + E y + F = 0 about the mean (for conditioning).
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d q = p - mean;
    const Eigen::Vector3d row(q.x(), q.y(), 1.0);
    ata += row * row.transpose();
    atb -= row * q.squaredNorm();
  }
  const Eigen::Vector3d def = ata.ldlt().solve(atb);
  Circle circle;
  circle.centre = Eigen::Vector2d(-def.x() / 2, -def.y() / 2);
  const double r2 = circle.centre.squaredNorm() - def.z();
  if (!std::isfinite(r2) || r2 <= 0) return std::nullopt;
  circle.radius = std::sqrt(r2);
  circle.centre += mean;
  return circle;
}

// A leg's circle when a stray stripe may cling to its outline (a wrong view's, a few cm
// off): of 64 circles through three of its points (a fixed pseudo-random choice), the one
// the most points lie within 5 mm of, refitted on those points. A leg's section is round
// to a few mm, so its outline outvotes a stripe; the plain fit would average them.
std::optional<Circle> FitLegCircle(const std::vector<Eigen::Vector2d>& points) {
  constexpr double kBand = 5.0;
  const size_t n = points.size();
  if (n < 12) return FitCircle(points);
  uint64_t state = 0x9e3779b97f4a7c15ull ^ n;
  auto pick = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<size_t>((state >> 33) % n);
  };
  auto near = [&](const Circle& c) {
    std::vector<Eigen::Vector2d> on;
    for (const Eigen::Vector2d& p : points)
      if (std::abs((p - c.centre).norm() - c.radius) < kBand) on.push_back(p);
    return on;
  };
  std::optional<Circle> best;
  size_t best_count = 0;
  for (int trial = 0; trial < 64; ++trial) {
    const Eigen::Vector2d a = points[pick()], b = points[pick()], c = points[pick()];
    // The circle through a, b, c: its centre o solves 2 (b - a) . o = |b|^2 - |a|^2, and c's.
    Eigen::Matrix2d m;
    m << 2 * (b - a).transpose(), 2 * (c - a).transpose();
    if (std::abs(m.determinant()) < 1e-6) continue;
    const Eigen::Vector2d o = m.inverse() * Eigen::Vector2d(b.squaredNorm() - a.squaredNorm(),
                                                            c.squaredNorm() - a.squaredNorm());
    const Circle candidate{o, (a - o).norm()};
    size_t count = 0;
    for (const Eigen::Vector2d& p : points)
      count += std::abs((p - candidate.centre).norm() - candidate.radius) < kBand;
    if (count > best_count) {
      best_count = count;
      best = candidate;
    }
  }
  if (!best || best_count < n / 2) return FitCircle(points);
  std::optional<Circle> refit = FitCircle(near(*best));
  if (refit) refit = FitCircle(near(*refit));
  return refit ? refit : FitCircle(points);
}

// The long axis of the ellipse through a group's points (general conic, least squares):
// its direction and the ratio of the axes. Empty when the points fit no ellipse.
struct Axis {
  Eigen::Vector2d direction;
  double ratio = 1.0;
};
std::optional<Axis> FitEllipseAxis(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 10) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  // x^2 + B xy + C y^2 + D x + E y + F = 0 (an ellipse has a non-zero x^2 term).
  Eigen::Matrix<double, 5, 5> ata = Eigen::Matrix<double, 5, 5>::Zero();
  Eigen::Matrix<double, 5, 1> atb = Eigen::Matrix<double, 5, 1>::Zero();
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d q = p - mean;
    Eigen::Matrix<double, 5, 1> row;
    row << q.x() * q.y(), q.y() * q.y(), q.x(), q.y(), 1.0;
    ata += row * row.transpose();
    atb -= row * q.x() * q.x();
  }
  const Eigen::Matrix<double, 5, 1> c = ata.ldlt().solve(atb);
  Eigen::Matrix2d form;
  form << 1.0, c(0) / 2, c(0) / 2, c(1);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(form);
  const Eigen::Vector2d w = eigen.eigenvalues();  // ascending
  if (!(w(0) > 0) || !std::isfinite(w(1))) return std::nullopt;
  return Axis{eigen.eigenvectors().col(0), std::sqrt(w(1) / w(0))};
}

// An angle folded into (-90, 90] degrees: the direction of an axis, which has no sign.
double FoldAxisDeg(double deg) {
  while (deg > 90.0) deg -= 180.0;
  while (deg <= -90.0) deg += 180.0;
  return deg;
}
double WrapDeg(double deg) {
  while (deg > 180.0) deg -= 360.0;
  while (deg <= -180.0) deg += 360.0;
  return deg;
}

// The cloud sorted by height, with horizontal sections taken from it in the world frame or
// in the body's frame (forward, left) about the ankles' centre.
class Sections {
 public:
  explicit Sections(std::vector<Eigen::Vector3d> points) : points_(std::move(points)) {
    std::sort(points_.begin(), points_.end(),
              [](const auto& a, const auto& b) { return a.z() < b.z(); });
  }
  const std::vector<Eigen::Vector3d>& points() const { return points_; }
  double top() const { return points_.back().z(); }

  void SetBodyFrame(const Eigen::Vector2d& centre, double yaw_rad) {
    centre_ = centre;
    forward_ = Eigen::Vector2d(std::sin(yaw_rad), -std::cos(yaw_rad));
    left_ = Eigen::Vector2d(std::cos(yaw_rad), std::sin(yaw_rad));
    body_ = true;
  }
  // The points with |z - z0| < half: world (x, y), or body (forward, left) once set.
  std::vector<Eigen::Vector2d> At(double z0, double half) const {
    const auto first = std::lower_bound(points_.begin(), points_.end(), z0 - half,
                                        [](const auto& p, double z) { return p.z() < z; });
    std::vector<Eigen::Vector2d> out;
    for (auto it = first; it != points_.end() && it->z() < z0 + half; ++it) {
      const Eigen::Vector2d xy = it->head<2>();
      out.push_back(body_ ? ToBody(xy) : xy);
    }
    return out;
  }
  Eigen::Vector2d ToBody(const Eigen::Vector2d& xy) const {
    const Eigen::Vector2d d = xy - centre_;
    return {d.dot(forward_), d.dot(left_)};
  }
  Eigen::Vector2d ToWorld(const Eigen::Vector2d& body) const {
    return centre_ + body.x() * forward_ + body.y() * left_;
  }

 private:
  std::vector<Eigen::Vector3d> points_;
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d forward_{0.0, -1.0}, left_{1.0, 0.0};
  bool body_ = false;
};

// The two legs in a section: the two largest groups, of similar size and radius, each a
// circle no wider than a leg, near each other. Empty when the section shows no two legs.
std::optional<std::pair<Circle, Circle>> TwoLegs(const std::vector<Blob>& blobs, double stature) {
  if (blobs.size() < 2 || blobs[1].points.size() < 15 ||
      blobs[1].points.size() < 0.3 * blobs[0].points.size()) {
    return std::nullopt;
  }
  const auto a = FitLegCircle(blobs[0].points), b = FitLegCircle(blobs[1].points);
  if (!a || !b) return std::nullopt;
  const double max_radius = 0.12 * stature;
  if (a->radius > max_radius || b->radius > max_radius) return std::nullopt;
  if (std::max(a->radius, b->radius) > 1.6 * std::min(a->radius, b->radius)) return std::nullopt;
  // Apart as two legs are (not two arcs of one ring), and near each other.
  const double apart = (a->centre - b->centre).norm();
  if (apart < 1.2 * std::max(a->radius, b->radius) || apart > 0.35 * stature) return std::nullopt;
  return std::pair{*a, *b};
}

// Both legs' centres at one height (world x, y).
struct LegPair {
  double z;
  Eigen::Vector2d a, b;  // a: the one further along +x
};

// The legs in the sections from the shins to the thighs.
std::vector<LegPair> FindLegs(const Sections& sections, double stature) {
  std::vector<LegPair> pairs;
  for (double f = kLegsFrom; f <= kLegsTo + 1e-9; f += kLegsStep) {
    const double z = f * stature;
    const auto legs = TwoLegs(Blobs(sections.At(z, 5.0)), stature);
    if (!legs) continue;
    LegPair pair{z, legs->first.centre, legs->second.centre};
    if (pair.a.x() < pair.b.x()) std::swap(pair.a, pair.b);
    pairs.push_back(pair);
  }
  return pairs;
}

// Least-squares line v = p + q z through (z, v) pairs; after one pass the points off by more
// than 3 median deviations (and 3 mm) are dropped and the line refitted.
std::optional<Eigen::Vector2d> FitLine(const std::vector<Eigen::Vector2d>& zv) {
  auto fit = [](const std::vector<Eigen::Vector2d>& s) -> std::optional<Eigen::Vector2d> {
    if (s.size() < 3) return std::nullopt;
    Eigen::MatrixXd a(s.size(), 2);
    Eigen::VectorXd b(s.size());
    for (size_t i = 0; i < s.size(); ++i) {
      a(i, 0) = 1.0;
      a(i, 1) = s[i].x();
      b(i) = s[i].y();
    }
    return Eigen::Vector2d(a.colPivHouseholderQr().solve(b));
  };
  const auto first = fit(zv);
  if (!first) return std::nullopt;
  std::vector<double> residuals;
  for (const Eigen::Vector2d& p : zv)
    residuals.push_back(std::abs(p.y() - (first->x() + first->y() * p.x())));
  const double limit = std::max(3.0, 3.0 * 1.4826 * Median(residuals));
  std::vector<Eigen::Vector2d> kept;
  for (size_t i = 0; i < zv.size(); ++i)
    if (residuals[i] <= limit) kept.push_back(zv[i]);
  return fit(kept);
}

// The trunk's group in a section between the wrists and the armpits: the largest.
const Blob* TrunkOf(const std::vector<Blob>& blobs) {
  return !blobs.empty() && blobs.front().points.size() >= 20 ? &blobs.front() : nullptr;
}

// The group nearest the body's axis with enough points (the neck, the head).
const Blob* NearestAxis(const std::vector<Blob>& blobs, size_t min_points) {
  const Blob* best = nullptr;
  for (const Blob& b : blobs) {
    if (b.points.size() < min_points) continue;
    if (!best || b.mean.norm() < best->mean.norm()) best = &b;
  }
  return best;
}

std::string Round5(double deg) {
  return std::to_string(std::max(5, static_cast<int>(std::lround(std::abs(deg) / 5.0)) * 5));
}

class Checker {
 public:
  Checker(const std::vector<Eigen::Vector3d>& points, const PoseOptions& options)
      : options_(options), sections_(WithoutStrays(points)) {}

  PoseReport Run() {
    if (const std::string reason = NotAPerson(); !reason.empty()) {
      report_.reason = reason;
      report_.advice = {
          "The scan does not show a standing person: check that the person "
          "stands in the cabinet and scan again."};
      return std::move(report_);
    }
    report_.checked = true;
    report_.head_top_seen_mm = sections_.top();
    stature_ = sections_.top();
    HeadTop();
    HeadCut();
    Legs();
    if (!legs_found_) TrunkYaw();
    Facing();
    sections_.SetBodyFrame(report_.centre_mm, yaw_rad_);
    Arms();
    Lean();
    HeadTurn();
    Judge();
    return std::move(report_);
  }

 private:
  // Why the cloud cannot be a person standing on the floor, or "".
  std::string NotAPerson() const {
    const auto& points = sections_.points();
    if (points.size() < 1000)
      return "too few points for a person (" + std::to_string(points.size()) + ")";
    if (sections_.top() < 1000.0) return "nothing in the cloud stands taller than 1 m";
    // A scan may miss the feet (a sweep that starts high): the legs must reach the shins.
    if (points.front().z() > 0.25 * sections_.top()) {
      return "nothing stands on the floor (the lowest point is " +
             std::to_string(static_cast<int>(points.front().z())) + " mm up)";
    }
    return "";
  }

  // A head above the cabinet's reach is cut off where the scan ends: the stations then come
  // from the crotch, the highest height at which the legs are seen apart. The head is cut
  // when the cloud ends within 15 mm of the reach, unless its cap closes below the reach and
  // its margin.
  void HeadCut() {
    const std::optional<double> reach = options_.reach.top_mm();
    const std::optional<double> cap = report_.head_top_mm.value;
    head_cut_ = reach && sections_.top() >= *reach - 15.0 &&
                !(cap && *cap <= *reach + options_.tolerances.reach_margin_mm);
    if (!head_cut_) return;
    report_.head_top_mm.value.reset();
    report_.head_top_mm.note = "the head reaches above the cabinet's reach";
    // The top of the run of sections with two legs that starts below the knees (a miss or
    // three on the way allowed; two arms higher up are not legs).
    double crotch = 0.0;
    for (double z = 0.25 * sections_.top(); z < 0.7 * sections_.top(); z += 10.0) {
      if (crotch > 0 && z - crotch > 40.0) break;
      if (TwoLegs(Blobs(sections_.At(z, 5.0)), sections_.top())) crotch = z;
    }
    stature_ = std::max(stature_, crotch / kCrotch);
  }

  void Legs() {
    const std::vector<LegPair> pairs = FindLegs(sections_, stature_);
    if (pairs.size() < 4) {
      report_.feet_spread_mm.note = report_.hip_spread_mm.note =
          "the legs were not seen apart (feet together?)";
      report_.feet_spread_mm.ok = false;
      return;
    }
    legs_found_ = true;
    Eigen::Vector2d direction = Eigen::Vector2d::Zero(), ankles = Eigen::Vector2d::Zero();
    std::vector<double> feet;
    std::vector<Eigen::Vector2d> spread_at;
    int ankle_levels = 0;
    for (const LegPair& p : pairs) {
      direction += (p.a - p.b).normalized();
      spread_at.emplace_back(p.z, (p.a - p.b).norm());
      if (p.z <= kAnklesTo * stature_ + 1e-6) {
        feet.push_back((p.a - p.b).norm());
        ankles += 0.5 * (p.a + p.b);
        ++ankle_levels;
      }
    }
    if (ankle_levels == 0) {  // the shins were not seen apart: the lowest pair stands in
      feet.push_back((pairs.front().a - pairs.front().b).norm());
      ankles = 0.5 * (pairs.front().a + pairs.front().b);
      ankle_levels = 1;
    }
    yaw_rad_ = std::atan2(direction.y(), direction.x());
    report_.yaw_from = "legs";
    report_.centre_mm = ankles / ankle_levels;
    report_.feet_spread_mm.value = Median(feet);
    if (const auto line = FitLine(spread_at)) {
      report_.hip_spread_mm.value = line->x() + line->y() * kHipJoint * stature_;
    }
  }

  // Without the legs: the trunk's sections are wider left-right than front-back.
  void TrunkYaw() {
    std::vector<double> yaws;
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    int centres = 0;
    for (double f = kTrunkFrom; f <= kTrunkTo + 1e-9; f += 0.01) {
      const std::vector<Blob> blobs = Blobs(sections_.At(f * stature_, 5.0));
      if (blobs.empty()) continue;
      const Blob& trunk = blobs.front();
      const auto axis = FitEllipseAxis(trunk.points);
      if (!axis || axis->ratio < 1.1) continue;
      yaws.push_back(FoldAxisDeg(Degrees(std::atan2(axis->direction.y(), axis->direction.x()))));
      centre += trunk.mean;
      ++centres;
    }
    if (yaws.empty()) {
      report_.yaw_deg.note = "neither the legs nor the trunk show which way the body faces";
      return;
    }
    yaw_rad_ = Median(yaws) * kPi / 180.0;
    report_.yaw_from = "trunk";
    report_.centre_mm = centre / centres;
  }

  // The feet point forward: the toes reach further ahead of the ankles than the heels
  // behind them. Facing the mirrors, the other way round. Where neither end reaches
  // clearly further (legs without feet, as the mannequin's) the legs' direction stands:
  // the median of what is seen there swings with which frames a sparse sweep kept.
  void Facing() {
    if (!legs_found_ && report_.yaw_from.empty()) return;
    sections_.SetBodyFrame(report_.centre_mm, yaw_rad_);
    std::vector<double> ahead;
    for (const Eigen::Vector3d& p : sections_.points()) {
      if (p.z() > 0.03 * stature_) break;
      ahead.push_back(sections_.ToBody(p.head<2>()).x());
    }
    if (ahead.size() >= 20) {
      const double toes = Quantile(ahead, 0.95), heels = -Quantile(ahead, 0.05);
      if (heels - toes > kFeetMargin * stature_) yaw_rad_ += kPi;
    }
    report_.yaw_deg.value = WrapDeg(Degrees(yaw_rad_));
  }

  // Each arm: the group beside the trunk in sections between the wrists and the armpit; its
  // centres lie on the arm's axis, whose slope from vertical in the frontal plane is the
  // abduction.
  void Arms() {
    std::array<std::vector<Eigen::Vector2d>, 2> lateral;  // (z, left coordinate) per side
    for (double z = kArmsFrom * stature_; z <= kArmsTo * stature_; z += 5.0) {
      const std::vector<Blob> blobs = Blobs(sections_.At(z, 2.5));
      const Blob* trunk = TrunkOf(blobs);
      if (!trunk) continue;
      for (int side = 0; side < 2; ++side) {  // 0 left (+), 1 right (-)
        const Blob* arm = nullptr;
        for (const Blob& b : blobs) {
          const bool beside = side == 0 ? b.min.y() > trunk->max.y() : b.max.y() < trunk->min.y();
          if (beside && b.points.size() >= 10 && (!arm || b.points.size() > arm->points.size()))
            arm = &b;
        }
        if (!arm) continue;
        if (const auto circle = FitCircle(arm->points)) {
          lateral[side].emplace_back(z, circle->centre.y());
        }
      }
    }
    for (int side = 0; side < 2; ++side) {
      PoseFigure& figure = report_.arm_abduction_deg[side];
      const auto& s = lateral[side];
      const std::optional<Eigen::Vector2d> line =
          s.size() >= 6 && s.back().x() - s.front().x() >= 0.04 * stature_ ? FitLine(s)
                                                                           : std::nullopt;
      if (!line) {
        figure.note = "the arm was not seen apart from the body";
        continue;
      }
      const double outward_per_mm_down = side == 0 ? -line->y() : line->y();
      figure.value = Degrees(std::atan(outward_per_mm_down));
    }
  }

  // The neck's centre ahead of (+) or behind the ankles, as an angle about them.
  void Lean() {
    std::vector<double> leans;
    for (double f = kNeckFrom; f <= kNeckTo + 1e-9; f += 0.01) {
      const double z = f * stature_;
      if (z > sections_.top() - 20.0) break;
      const std::vector<Blob> blobs = Blobs(sections_.At(z, 5.0));
      const Blob* neck = NearestAxis(blobs, 20);
      if (!neck) continue;
      if (const auto circle = FitCircle(neck->points)) {
        leans.push_back(Degrees(std::atan2(circle->centre.x(), z - kAnkle * stature_)));
      }
    }
    if (leans.empty()) {
      report_.lean_deg.note = "the neck was not seen";
      return;
    }
    report_.lean_deg.value = Median(leans);
  }

  // The head's sections are longer front to back: their long axis from the body's front.
  void HeadTurn() {
    if (head_cut_) {
      report_.head_turn_deg.note = "the head reaches above the cabinet's reach";
      return;
    }
    std::vector<double> turns;
    // From 40 mm below the highest point down to just above the chin.
    for (double z = sections_.top() - 40.0; z >= kHeadFrom * stature_; z -= 5.0) {
      const std::vector<Blob> blobs = Blobs(sections_.At(z, 2.5));
      const Blob* head = NearestAxis(blobs, 30);
      if (!head) continue;
      const auto axis = FitEllipseAxis(head->points);
      if (!axis || axis->ratio < 1.12) continue;
      turns.push_back(FoldAxisDeg(Degrees(std::atan2(axis->direction.y(), axis->direction.x()))));
    }
    if (turns.size() < 3) {
      report_.head_turn_deg.note = "the head's sections show no clear front";
      return;
    }
    report_.head_turn_deg.value = Median(turns);
  }

  // The top of the head is seen from no camera: the cap below it is fitted and extrapolated
  // (host/measurement's head cap). Before the body's frame is known: the head's axis is the
  // largest group's centre 60 mm below the highest point, the fit finds the head's yaw.
  void HeadTop() {
    const double top = sections_.top();
    const std::vector<Blob> blobs = Blobs(sections_.At(top - 60.0, 10.0));
    if (blobs.empty()) return;
    const Eigen::Vector2d axis = blobs.front().mean;
    std::vector<Eigen::Vector3d> cap;
    for (auto it = sections_.points().rbegin(); it != sections_.points().rend(); ++it) {
      if (it->z() < top - 50.0) break;
      if ((it->head<2>() - axis).norm() <= 150.0) cap.push_back(*it);
    }
    const auto fit = measurement::FitHeadCap(cap, Eigen::Vector2d::UnitX());
    if (!fit || fit->rms_mm > 3.0 || fit->top.z() < top - 1.0 || fit->top.z() > top + 80.0) {
      report_.head_top_mm.note = "the cap below the top of the head fits no head";
      return;
    }
    report_.head_top_mm.value = fit->top.z();
  }

  void Judge() {
    const PoseTolerances& t = options_.tolerances;
    std::vector<std::string>& advice = report_.advice;
    // Yaw first: a turned body also moves the arms and legs the other checks see.
    if (report_.yaw_deg.value) {
      const double yaw = *report_.yaw_deg.value;
      report_.yaw_deg.ok = std::abs(yaw) <= t.yaw_max_deg;
      if (std::abs(yaw) > 90.0) {
        advice.push_back("Turn around to face the camera.");
      } else if (!report_.yaw_deg.ok) {
        // + is turned to the person's left: they turn back to their right.
        advice.push_back("Turn about " + Round5(yaw) + "° to your " + (yaw > 0 ? "right" : "left") +
                         " to face the camera.");
      }
    }
    if (!report_.yaw_deg.value) {
      advice.push_back("Stand in the middle of the cabinet, facing the camera.");
    }
    PoseFigure& feet = report_.feet_spread_mm;
    if (feet.value && report_.hip_spread_mm.value && *report_.hip_spread_mm.value > 0) {
      const double ratio = *feet.value / *report_.hip_spread_mm.value;
      feet.ok = ratio >= t.feet_min_ratio && ratio <= t.feet_max_ratio;
      if (ratio < t.feet_min_ratio) {
        advice.push_back("Step onto the footprints: feet hip width apart.");
      } else if (ratio > t.feet_max_ratio) {
        advice.push_back("Bring your feet closer together, onto the footprints.");
      }
    } else if (!feet.value) {
      advice.push_back("Step onto the footprints: feet hip width apart.");
    }
    std::array<int, 2> low{}, high{};
    for (int side = 0; side < 2; ++side) {
      PoseFigure& arm = report_.arm_abduction_deg[side];
      low[side] = !arm.value || *arm.value < t.arm_min_deg;
      high[side] = arm.value && *arm.value > t.arm_max_deg;
      arm.ok = !low[side] && !high[side];
    }
    const char* sides[] = {"left", "right"};
    if (low[0] && low[1]) {
      advice.push_back(
          "Hold your arms a little further from your body, about a hand's width at the hips.");
    } else if (low[0] || low[1]) {
      advice.push_back(std::string("Hold your ") + sides[low[0] ? 0 : 1] +
                       " arm a little further from your body, like the other.");
    }
    if (high[0] && high[1]) {
      advice.push_back("Lower your arms a little: about a hand's width from your hips.");
    } else if (high[0] || high[1]) {
      advice.push_back(std::string("Lower your ") + sides[high[0] ? 0 : 1] +
                       " arm a little, like the other.");
    }
    if (report_.lean_deg.value) {
      const double lean = *report_.lean_deg.value;
      report_.lean_deg.ok = std::abs(lean) <= t.lean_max_deg;
      if (!report_.lean_deg.ok) {
        advice.push_back(std::string("Stand up straight, weight on both feet: you lean ") +
                         (lean > 0 ? "forward." : "back."));
      }
    }
    if (report_.head_turn_deg.value) {
      report_.head_turn_deg.ok = std::abs(*report_.head_turn_deg.value) <= t.head_turn_max_deg;
      if (!report_.head_turn_deg.ok) {
        advice.push_back("Look straight ahead at the mark on the mirror.");
      }
    }
    if (const std::optional<double> reach = options_.reach.top_mm()) {
      const double head = report_.head_top_mm.value.value_or(report_.head_top_seen_mm);
      report_.head_top_mm.ok = !head_cut_ && head <= *reach + t.reach_margin_mm;
      if (!report_.head_top_mm.ok) {
        advice.push_back("You are taller than the cabinet can scan (up to " +
                         std::to_string(static_cast<int>(std::lround(*reach / 10.0))) +
                         " cm): the top of your head will be missing.");
      }
    }
    report_.within_protocol = report_.yaw_deg.value && report_.yaw_deg.ok && feet.ok &&
                              report_.arm_abduction_deg[0].ok && report_.arm_abduction_deg[1].ok &&
                              report_.lean_deg.ok && report_.head_turn_deg.ok &&
                              report_.head_top_mm.ok;
  }

  const PoseOptions& options_;
  Sections sections_;
  PoseReport report_;
  double stature_ = 0.0;  // for the stations: the highest point, or from the crotch
  bool head_cut_ = false;
  bool legs_found_ = false;
  double yaw_rad_ = 0.0;
};

nlohmann::json FigureJson(const PoseFigure& figure, int decimals) {
  if (!figure.value) return nullptr;
  const double scale = std::pow(10.0, decimals);
  return std::round(*figure.value * scale) / scale + 0.0;  // + 0.0: no "-0.0"
}

}  // namespace

std::optional<double> CabinetReach::top_mm() const {
  if (mirror_top_mm && laser_top_mm) return std::min(*mirror_top_mm, *laser_top_mm);
  return mirror_top_mm ? mirror_top_mm : laser_top_mm;
}

std::string CabinetReach::limited_by() const {
  if (!top_mm()) return "";
  if (mirror_top_mm && *top_mm() == *mirror_top_mm) return "mirrors";
  return "lasers";
}

CabinetReach ReachOf(const Calibration& calibration, std::optional<double> sweep_end_mm,
                     std::optional<double> board_mirror_top_mm) {
  CabinetReach reach;
  for (const CalibrationMirror& mirror : calibration.mirrors) {
    for (const Eigen::Vector3d& corner : mirror.corners_mm) {
      reach.mirror_top_mm = std::max(reach.mirror_top_mm.value_or(-1e18), corner.z());
    }
  }
  if (!reach.mirror_top_mm) reach.mirror_top_mm = board_mirror_top_mm;
  if (sweep_end_mm && calibration.lasers) {
    const CalibrationLasers& lasers = *calibration.lasers;
    // The readback is laser 0's height plus the offset (0 when not measured).
    reach.laser_top_mm = *sweep_end_mm - lasers.readback_offset_mm.value_or(0.0) +
                         lasers.OffsetOf(std::max(lasers.count - 1, 0));
  }
  return reach;
}

PoseReport CheckPose(const std::vector<Eigen::Vector3d>& points, const PoseOptions& options) {
  std::vector<Eigen::Vector3d> usable;
  usable.reserve(points.size());
  for (const Eigen::Vector3d& p : points)
    if (p.allFinite()) usable.push_back(p);
  return Checker(usable, options).Run();
}

PoseReport CheckPose(const PointCloud& cloud, const PoseOptions& options) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(cloud.points.size());
  for (const CloudPoint& p : cloud.points) points.push_back(p.point_in_world.cast<double>());
  return CheckPose(points, options);
}

nlohmann::json ToJson(const PoseReport& r, const PoseOptions& options) {
  nlohmann::json json = {
      {"checked", r.checked}, {"within_protocol", r.within_protocol}, {"advice", r.advice}};
  if (!r.checked) {
    json["reason"] = r.reason;
    return json;
  }
  const std::optional<double> reach = options.reach.top_mm();
  json.update({{"feet_spread_mm", FigureJson(r.feet_spread_mm, 0)},
               {"hip_spread_mm", FigureJson(r.hip_spread_mm, 0)},
               {"arm_abduction_deg",
                {{"left", FigureJson(r.arm_abduction_deg[0], 1)},
                 {"right", FigureJson(r.arm_abduction_deg[1], 1)}}},
               {"yaw_deg", FigureJson(r.yaw_deg, 1)},
               {"yaw_from", r.yaw_from},
               {"lean_deg", FigureJson(r.lean_deg, 1)},
               {"head_turn_deg", FigureJson(r.head_turn_deg, 1)},
               {"head_top_mm", FigureJson(r.head_top_mm, 0)},
               {"head_top_seen_mm", std::round(r.head_top_seen_mm)},
               {"reach_mm", reach ? nlohmann::json(std::round(*reach)) : nlohmann::json()},
               {"reach_limited_by", options.reach.limited_by()},
               {"centre_mm", {std::round(r.centre_mm.x()), std::round(r.centre_mm.y())}}});
  // Which figures are off, and why a figure is missing.
  nlohmann::json off = nlohmann::json::array(), notes = nlohmann::json::object();
  const std::pair<const char*, const PoseFigure*> figures[] = {
      {"feet_spread_mm", &r.feet_spread_mm},
      {"arm_abduction_left", &r.arm_abduction_deg[0]},
      {"arm_abduction_right", &r.arm_abduction_deg[1]},
      {"yaw_deg", &r.yaw_deg},
      {"lean_deg", &r.lean_deg},
      {"head_turn_deg", &r.head_turn_deg},
      {"head_top_mm", &r.head_top_mm},
      {"hip_spread_mm", &r.hip_spread_mm}};
  for (const auto& [name, figure] : figures) {
    if (!figure->ok) off.push_back(name);
    if (!figure->note.empty()) notes[name] = figure->note;
  }
  json["off_protocol"] = off;
  json["notes"] = notes;
  const PoseTolerances& t = options.tolerances;
  json["tolerances"] = {{"arm_abduction_deg", {t.arm_min_deg, t.arm_max_deg}},
                        {"yaw_max_deg", t.yaw_max_deg},
                        {"lean_max_deg", t.lean_max_deg},
                        {"head_turn_max_deg", t.head_turn_max_deg},
                        {"feet_to_hip_spread", {t.feet_min_ratio, t.feet_max_ratio}},
                        {"reach_margin_mm", t.reach_margin_mm}};
  return json;
}

}  // namespace mirrorscan::pose

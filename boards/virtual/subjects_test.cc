#include "boards/virtual/subjects.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <numeric>
#include <ostream>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

namespace mirrorscan::virtual_cabinet {

// Readable test names on failure (gtest finds this by argument-dependent lookup).
void PrintTo(const MannequinParams& p, std::ostream* out) {
  *out << "height " << p.height_mm << ", girths " << p.chest_girth_mm << "/" << p.waist_girth_mm
       << "/" << p.hip_girth_mm << ", centre " << p.center_mm.transpose() << ", yaw " << p.yaw_deg;
}

namespace {

constexpr double kPi = std::numbers::pi;

// ---- Independent geometry helpers (nothing here comes from subjects.cc) -------------

// Triangles grouped by connected component (triangles sharing a vertex).
std::vector<std::vector<int>> Components(const TriangleMesh& mesh) {
  std::vector<int> parent(mesh.vertices.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&parent](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const Eigen::Vector3i& t : mesh.triangles) {
    parent[find(t[1])] = find(t[0]);
    parent[find(t[2])] = find(t[0]);
  }
  std::map<int, std::vector<int>> groups;
  for (int i = 0; i < static_cast<int>(mesh.triangles.size()); ++i) {
    groups[find(mesh.triangles[i][0])].push_back(i);
  }
  std::vector<std::vector<int>> result;
  for (auto& [root, triangles] : groups) result.push_back(std::move(triangles));
  return result;
}

// Closed and consistently oriented: every directed edge appears exactly once and its
// reverse exactly once (so every undirected edge is used exactly twice).
::testing::AssertionResult ClosedAndOriented(const TriangleMesh& mesh,
                                             const std::vector<int>& triangles) {
  std::map<std::pair<int, int>, int> directed;
  for (int i : triangles) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    if (count != 1) return ::testing::AssertionFailure() << "directed edge used " << count;
    const auto reverse = directed.find({edge.second, edge.first});
    if (reverse == directed.end()) return ::testing::AssertionFailure() << "open edge";
  }
  return ::testing::AssertionSuccess();
}

double SignedVolume(const TriangleMesh& mesh, const std::vector<int>& triangles) {
  double volume = 0.0;
  for (int i : triangles) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]])) / 6.0;
  }
  return volume;
}

std::vector<int> AllTriangles(const TriangleMesh& mesh) {
  std::vector<int> all(mesh.triangles.size());
  std::iota(all.begin(), all.end(), 0);
  return all;
}

struct Segment {
  Eigen::Vector2d a, b;
};

// Intersects triangles with the plane z = z0. A vertex exactly on the plane counts as
// above it, so a ring of vertices lying in the plane yields exactly its polygon.
std::vector<Segment> Slice(const TriangleMesh& mesh, const std::vector<int>& triangles, double z0) {
  std::vector<Segment> segments;
  for (int i : triangles) {
    std::vector<Eigen::Vector2d> points;
    const Eigen::Vector3i& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& p = mesh.vertices[t[k]];
      const Eigen::Vector3d& q = mesh.vertices[t[(k + 1) % 3]];
      if ((p.z() >= z0) == (q.z() >= z0)) continue;
      const double s = (z0 - p.z()) / (q.z() - p.z());
      points.push_back((p + s * (q - p)).head<2>());
    }
    if (points.size() == 2) segments.push_back({points[0], points[1]});
  }
  return segments;
}

double Length(const std::vector<Segment>& segments) {
  double length = 0.0;
  for (const Segment& s : segments) length += (s.b - s.a).norm();
  return length;
}

// Even-odd ray cast along +x from `point`.
bool Encloses(const std::vector<Segment>& segments, const Eigen::Vector2d& point) {
  int crossings = 0;
  for (const Segment& s : segments) {
    if ((s.a.y() > point.y()) == (s.b.y() > point.y())) continue;
    const double x = s.a.x() + (point.y() - s.a.y()) / (s.b.y() - s.a.y()) * (s.b.x() - s.a.x());
    if (x > point.x()) ++crossings;
  }
  return crossings % 2 == 1;
}

double PointSegmentDistance(const Eigen::Vector2d& p, const Segment& s) {
  const Eigen::Vector2d d = s.b - s.a;
  const double n2 = d.squaredNorm();
  const double t = n2 > 0 ? std::clamp((p - s.a).dot(d) / n2, 0.0, 1.0) : 0.0;
  return (s.a + t * d - p).norm();
}

double MinDistance(const std::vector<Segment>& from, const std::vector<Segment>& to) {
  double best = std::numeric_limits<double>::infinity();
  for (const Segment& f : from) {
    for (const Eigen::Vector2d& p : {f.a, f.b}) {
      for (const Segment& s : to) best = std::min(best, PointSegmentDistance(p, s));
    }
  }
  return best;
}

// Ellipse perimeter by the trapezoid rule, which converges geometrically for a smooth
// periodic integrand: an independent check of the AGM formula.
double NumericEllipsePerimeter(double a, double b) {
  constexpr int kSteps = 20000;
  double sum = 0.0;
  for (int i = 0; i < kSteps; ++i) {
    const double t = 2.0 * kPi * i / kSteps;
    sum += std::hypot(a * std::sin(t), b * std::cos(t));
  }
  return sum * 2.0 * kPi / kSteps;
}

// Every connected component is closed, outward (positive volume), and the metadata's
// parts are exactly those components.
void ExpectClosedParts(const Subject& subject, size_t expected_parts) {
  const std::vector<std::vector<int>> components = Components(subject.mesh);
  EXPECT_EQ(components.size(), expected_parts);
  for (const std::vector<int>& c : components) {
    EXPECT_TRUE(ClosedAndOriented(subject.mesh, c));
    EXPECT_GT(SignedVolume(subject.mesh, c), 0.0);
  }
  const nlohmann::json& parts = subject.metadata.at("parts");
  ASSERT_EQ(parts.size(), expected_parts);
  std::set<std::vector<int>> from_components(components.begin(), components.end());
  for (const nlohmann::json& part : parts) {
    std::vector<int> range(part.at("triangle_count").get<int>());
    std::iota(range.begin(), range.end(), part.at("first_triangle").get<int>());
    EXPECT_EQ(from_components.count(range), 1u) << part.dump();
  }
}

Subject Parse(const std::string& text, const std::filesystem::path& base_dir = {}) {
  const nlohmann::json json = nlohmann::json::parse(text);
  return ParseSubject(JsonReader(json, "scene.json", "subject"), base_dir);
}

std::string ParseError(const std::string& text, const std::filesystem::path& base_dir = {}) {
  try {
    Parse(text, base_dir);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

// ---- Ellipse perimeter ---------------------------------------------------------------

TEST(SubjectEllipseTest, PerimeterMatchesNumericalIntegration) {
  EXPECT_NEAR(EllipsePerimeter(1.0, 1.0), 2.0 * kPi, 1e-14);
  EXPECT_NEAR(EllipsePerimeter(2.0, 0.0), 8.0, 1e-14);
  for (const auto& [a, b] : std::vector<std::pair<double, double>>{
           {1.0, 0.7}, {0.7, 1.0}, {178.0, 124.6}, {3.0, 1.0}, {10.0, 0.5}}) {
    const double numeric = NumericEllipsePerimeter(a, b);
    EXPECT_NEAR(EllipsePerimeter(a, b) / numeric, 1.0, 1e-12) << a << " x " << b;
  }
}

// ---- Mannequin -----------------------------------------------------------------------

class SubjectMannequinTest : public ::testing::TestWithParam<MannequinParams> {};

TEST_P(SubjectMannequinTest, GirthsHeightArmsAndClosure) {
  const MannequinParams p = GetParam();
  const Subject subject = MakeMannequin(p);
  EXPECT_EQ(subject.type, "mannequin");
  ExpectClosedParts(subject, 7);  // torso, 2 legs, 2 arms, neck, head

  const Eigen::AlignedBox3d box = subject.mesh.Bounds();
  EXPECT_NEAR(box.max().z(), p.height_mm, 0.01);
  EXPECT_NEAR(subject.metadata.at("height_mm").get<double>(), p.height_mm, 1e-12);
  EXPECT_NEAR(box.min().z(), 0.0, 1e-9);  // feet on the floor

  const std::vector<std::vector<int>> components = Components(subject.mesh);
  const Eigen::Vector2d axis = p.center_mm;
  const std::map<std::string, double> requested = {
      {"chest", p.chest_girth_mm}, {"waist", p.waist_girth_mm}, {"hip", p.hip_girth_mm}};
  for (const auto& [station, girth] : requested) {
    SCOPED_TRACE(station);
    const nlohmann::json& meta = subject.metadata.at(station);
    const double z = meta.at("z_mm").get<double>();
    const double meta_girth = meta.at("girth_mm").get<double>();
    const double a = meta.at("semi_axes_mm")[0].get<double>();
    const double b = meta.at("semi_axes_mm")[1].get<double>();
    EXPECT_NEAR(meta_girth / girth, 1.0, 1e-9);
    EXPECT_NEAR(NumericEllipsePerimeter(a, b) / girth, 1.0, 1e-9);

    // Exactly one part encloses the body axis at the station: the torso.
    std::vector<Segment> torso;
    std::vector<std::vector<Segment>> others;
    for (const std::vector<int>& c : components) {
      std::vector<Segment> segments = Slice(subject.mesh, c, z);
      if (segments.empty()) continue;
      if (Encloses(segments, axis)) {
        EXPECT_TRUE(torso.empty()) << "two parts enclose the axis";
        torso = std::move(segments);
      } else {
        others.push_back(std::move(segments));
      }
    }
    ASSERT_FALSE(torso.empty());
    for (const Segment& s : torso) {
      EXPECT_LT((s.a - axis).norm(), 300.0);
    }
    EXPECT_NEAR(Length(torso) / meta_girth, 1.0, 1e-3);
    if (station == "chest") {
      ASSERT_EQ(others.size(), 2u) << "the arms should cross the chest height";
    }
    for (const std::vector<Segment>& other : others) {
      EXPECT_GE(MinDistance(other, torso), 40.0);
      EXPECT_FALSE(Encloses(torso, other.front().a)) << "a part inside the torso's girth";
    }
  }
}

TEST_P(SubjectMannequinTest, TorsoRingsAreFineEnough) {
  const Subject subject = MakeMannequin(GetParam());
  const nlohmann::json& torso = subject.metadata.at("parts")[0];
  ASSERT_EQ(torso.at("name"), "torso");
  std::map<double, int> per_z;  // vertices per ring height
  const int first = torso.at("first_triangle"), count = torso.at("triangle_count");
  std::set<int> vertices;
  for (int i = first; i < first + count; ++i) {
    for (int k = 0; k < 3; ++k) vertices.insert(subject.mesh.triangles[i][k]);
  }
  for (int v : vertices) ++per_z[subject.mesh.vertices[v].z()];
  ASSERT_GT(per_z.size(), 2u);
  double previous = per_z.begin()->first;
  for (const auto& [z, n] : per_z) {
    EXPECT_LE(z - previous, 5.0 + 1e-9);
    previous = z;
    EXPECT_GE(n, 256) << "at z " << z;  // caps add one centre vertex to the end rings
  }
}

MannequinParams Custom() {
  MannequinParams p;
  p.height_mm = 1600.0;
  p.chest_girth_mm = 1100.0;
  p.waist_girth_mm = 950.0;
  p.hip_girth_mm = 1050.0;
  p.center_mm = Eigen::Vector2d(50.0, -20.0);
  p.yaw_deg = 30.0;
  return p;
}

std::string BodyName(const ::testing::TestParamInfo<MannequinParams>& param) {
  return param.index == 0 ? "Defaults" : "Custom";
}

INSTANTIATE_TEST_SUITE_P(Bodies, SubjectMannequinTest,
                         ::testing::Values(MannequinParams{}, Custom()), BodyName);

// The truth's girths against the mesh, sliced by this file's own helpers: the stations'
// ellipses, the thigh's circle, and the neck's.
TEST_P(SubjectMannequinTest, MeasurementTruthMatchesTheMeshSections) {
  const MannequinParams p = GetParam();
  const Subject subject = MakeMannequin(p);
  const nlohmann::json& truth = subject.metadata.at("truth");
  EXPECT_DOUBLE_EQ(truth.at("stature_mm").get<double>(), p.height_mm);
  for (const char* station : {"chest", "waist", "hip"}) {
    SCOPED_TRACE(station);
    const nlohmann::json& meta = subject.metadata.at(station);
    EXPECT_NEAR(truth.at(std::string(station) + "_z_mm").get<double>(),
                meta.at("z_mm").get<double>(), 0.05);
    EXPECT_NEAR(truth.at(std::string(station) + "_girth_mm").get<double>(),
                meta.at("girth_mm").get<double>(), 0.01);
  }
  // Each leg's section is a circle at the thigh height; the neck's at the neck's middle.
  auto part = [&subject](const std::string& name) {
    std::vector<int> triangles;
    for (const nlohmann::json& entry : subject.metadata.at("parts")) {
      if (entry.at("name") != name) continue;
      const int first = entry.at("first_triangle"), count = entry.at("triangle_count");
      for (int i = first; i < first + count; ++i) triangles.push_back(i);
    }
    return triangles;
  };
  for (const char* leg : {"left_leg", "right_leg"}) {
    const std::vector<Segment> segments =
        Slice(subject.mesh, part(leg), truth.at("thigh_z_mm").get<double>());
    EXPECT_NEAR(Length(segments), truth.at("thigh_girth_mm").get<double>(), 0.05) << leg;
  }
  EXPECT_NEAR(Length(Slice(subject.mesh, part("neck"), 0.856 * p.height_mm)),
              truth.at("neck_girth_mm").get<double>(), 0.05);
  // The shoulder points lie on the body's top, above the arms' joints and apart by the
  // shoulder breadth; arm length is shoulder to wrist.
  const Eigen::Vector3d left(truth.at("shoulder_points_mm")[0][0].get<double>(),
                             truth.at("shoulder_points_mm")[0][1].get<double>(),
                             truth.at("shoulder_points_mm")[0][2].get<double>());
  const Eigen::Vector3d wrist(truth.at("wrist_points_mm")[0][0].get<double>(),
                              truth.at("wrist_points_mm")[0][1].get<double>(),
                              truth.at("wrist_points_mm")[0][2].get<double>());
  EXPECT_GT(left.z(), 0.80 * p.height_mm);
  EXPECT_LT(left.z(), 0.86 * p.height_mm);
  EXPECT_NEAR((left - wrist).norm(), truth.at("arm_length_mm").get<double>(), 1e-9);
}

TEST(SubjectMannequinPoseTest, ArmAngleIsParsedAndChecked) {
  const Subject raised = Parse(R"({"type": "mannequin", "arm_angle_deg": 120})");
  EXPECT_DOUBLE_EQ(raised.metadata.at("arm_angle_deg").get<double>(), 120.0);
  EXPECT_TRUE(raised.metadata.at("truth").at("arm_length_mm").is_null());
  EXPECT_GT(raised.mesh.Bounds().max().z(), 1750.0);  // hands above the head
  const Subject near = Parse(R"({"type": "mannequin", "arm_angle_deg": 15})");
  EXPECT_DOUBLE_EQ(near.metadata.at("params").at("arm_angle_deg").get<double>(), 15.0);
  EXPECT_EQ(ParseError(R"({"type": "mannequin", "arm_angle_deg": 80})"),
            "scene.json: subject.arm_angle_deg: must hang the arms (4..60) or raise them "
            "(100..150)");
}

// ---- Cuboid --------------------------------------------------------------------------

TEST(SubjectCuboidTest, CornersFacesAndTripod) {
  CuboidParams p;
  p.center_mm = Eigen::Vector3d(12.0, -7.0, 1250.0);
  p.yaw_deg = 25.0;
  const Subject subject = MakeCuboidOnTripod(p);
  EXPECT_EQ(subject.type, "cuboid");
  ExpectClosedParts(subject, 5);  // cuboid, column, three legs

  const double c = std::cos(25.0 * kPi / 180.0), s = std::sin(25.0 * kPi / 180.0);
  const Eigen::Vector3d ex(c, s, 0), ey(-s, c, 0), ez(0, 0, 1);  // the cuboid's axes
  const nlohmann::json& corners = subject.metadata.at("corners_mm");
  ASSERT_EQ(corners.size(), 8u);
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d expected = p.center_mm + ((i & 1) ? 0.5 : -0.5) * 227.7 * ex +
                                     ((i & 2) ? 0.5 : -0.5) * 206.6 * ey +
                                     ((i & 4) ? 0.5 : -0.5) * 316.8 * ez;
    const Eigen::Vector3d actual(corners[i][0], corners[i][1], corners[i][2]);
    EXPECT_LT((actual - expected).norm(), 1e-9) << "corner " << i;
  }

  // The cuboid part: 12 triangles on the six face planes, normals along the faces'.
  const nlohmann::json& part = subject.metadata.at("parts")[0];
  ASSERT_EQ(part.at("name"), "cuboid");
  ASSERT_EQ(part.at("triangle_count"), 12);
  const std::vector<std::pair<Eigen::Vector3d, double>> faces = {{ex, 227.7 / 2}, {-ex, 227.7 / 2},
                                                                 {ey, 206.6 / 2}, {-ey, 206.6 / 2},
                                                                 {ez, 316.8 / 2}, {-ez, 316.8 / 2}};
  std::map<int, int> triangles_per_face;
  std::vector<int> cuboid_triangles;
  const int first = part.at("first_triangle");
  for (int t = first; t < first + 12; ++t) {
    cuboid_triangles.push_back(t);
    const Eigen::Vector3d normal = subject.mesh.TriangleNormal(t);
    int face = -1;
    for (int f = 0; f < 6; ++f) {
      if ((normal - faces[f].first).norm() < 1e-12) face = f;
    }
    ASSERT_GE(face, 0) << "triangle " << t << " normal " << normal.transpose();
    ++triangles_per_face[face];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& v = subject.mesh.vertices[subject.mesh.triangles[t][k]];
      EXPECT_NEAR((v - p.center_mm).dot(faces[face].first), faces[face].second, 1e-9);
    }
  }
  EXPECT_EQ(triangles_per_face.size(), 6u);
  EXPECT_NEAR(SignedVolume(subject.mesh, cuboid_triangles), 227.7 * 206.6 * 316.8, 1e-6);
  EXPECT_DOUBLE_EQ(subject.metadata.at("yaw_deg").get<double>(), 25.0);
  EXPECT_DOUBLE_EQ(subject.metadata.at("size_mm")[2].get<double>(), 316.8);

  // The tripod stands on the floor, reaches into the cuboid and is splayed.
  const double underside = p.center_mm.z() - 316.8 / 2;
  double top_of_tripod = 0.0, widest_foot = 0.0, lowest = 1e9;
  for (size_t v = 8; v < subject.mesh.vertices.size(); ++v) {
    const Eigen::Vector3d& x = subject.mesh.vertices[v];
    top_of_tripod = std::max(top_of_tripod, x.z());
    lowest = std::min(lowest, x.z());
    if (x.z() == 0.0) widest_foot = std::max(widest_foot, (x - p.center_mm).head<2>().norm());
  }
  EXPECT_GT(top_of_tripod, underside);
  EXPECT_LT(top_of_tripod, p.center_mm.z());
  EXPECT_EQ(lowest, 0.0);
  EXPECT_GT(widest_foot, 300.0);
}

// ---- Cylinder ------------------------------------------------------------------------

TEST(SubjectCylinderTest, SideVerticesOnTheRadius) {
  CylinderParams p;
  p.radius_mm = 140.0;
  p.center_mm = Eigen::Vector2d(30.0, -10.0);
  const Subject subject = MakeCylinder(p);
  ExpectClosedParts(subject, 1);
  std::set<double> angles;
  int side = 0;
  for (const Eigen::Vector3d& v : subject.mesh.vertices) {
    const Eigen::Vector2d d = v.head<2>() - p.center_mm;
    EXPECT_TRUE(v.z() == 400.0 || v.z() == 1400.0) << v.transpose();
    if (d.norm() < 1e-6) continue;  // a cap centre
    ++side;
    EXPECT_NEAR(d.norm(), 140.0, 1e-9);
    angles.insert(std::round(std::atan2(d.y(), d.x()) * 1e9));
  }
  EXPECT_GE(angles.size(), 360u);
  EXPECT_EQ(side, 2 * static_cast<int>(angles.size()));
  // Volume of the inscribed prism: n/2 r^2 sin(2 pi / n) h.
  const double n = static_cast<double>(angles.size());
  EXPECT_NEAR(SignedVolume(subject.mesh, AllTriangles(subject.mesh)),
              n / 2 * 140.0 * 140.0 * std::sin(2 * kPi / n) * 1000.0, 1e-3);
}

// ---- Parsing -------------------------------------------------------------------------

TEST(SubjectParseTest, DefaultsFromTheDocumentation) {
  const Subject cuboid = Parse(R"({"type": "cuboid"})");
  EXPECT_EQ(cuboid.metadata.at("size_mm"), nlohmann::json({227.7, 206.6, 316.8}));
  EXPECT_EQ(cuboid.metadata.at("center_mm"), nlohmann::json({0.0, 0.0, 1300.0}));
  EXPECT_EQ(cuboid.metadata.at("yaw_deg"), 0.0);

  const Subject cylinder = Parse(R"({"type": "cylinder"})");
  EXPECT_EQ(cylinder.metadata.at("params"),
            nlohmann::json::parse(R"({"radius_mm": 150.0, "height_mm": 1000.0,
                                      "bottom_mm": 400.0, "center_mm": [0.0, 0.0]})"));
  EXPECT_NEAR(cylinder.mesh.Bounds().max().z(), 1400.0, 1e-12);

  const Subject mannequin = Parse(R"({"type": "mannequin"})");
  EXPECT_EQ(mannequin.metadata.at("params"),
            nlohmann::json::parse(R"({"height_mm": 1750.0, "chest_girth_mm": 960.0,
                                      "waist_girth_mm": 800.0, "hip_girth_mm": 1000.0,
                                      "center_mm": [0.0, 0.0], "yaw_deg": 0.0,
                                      "arm_angle_deg": null})"));
  EXPECT_NEAR(mannequin.mesh.Bounds().max().z(), 1750.0, 0.01);

  const Subject none = Parse(R"({"type": "none"})");
  EXPECT_EQ(none.type, "none");
  EXPECT_TRUE(none.mesh.empty());
  EXPECT_TRUE(none.mesh.vertices.empty());
}

TEST(SubjectParseTest, ValuesAreUsed) {
  const Subject cuboid =
      Parse(R"({"type": "cuboid", "size_mm": [100, 200, 300], "center_mm": [1, 2, 1000],
                "yaw_deg": 90})");
  // Corner 1 is local (+x, -y, -z); yaw 90 maps local +x to world +y.
  const nlohmann::json& corner = cuboid.metadata.at("corners_mm")[1];
  EXPECT_NEAR(corner[0].get<double>(), 1.0 + 100.0, 1e-9);
  EXPECT_NEAR(corner[1].get<double>(), 2.0 + 50.0, 1e-9);
  EXPECT_NEAR(corner[2].get<double>(), 850.0, 1e-9);

  const Subject cylinder = Parse(R"({"type": "cylinder", "radius_mm": 80, "height_mm": 500,
                                     "bottom_mm": 100, "center_mm": [5, 6]})");
  const Eigen::AlignedBox3d box = cylinder.mesh.Bounds();
  EXPECT_NEAR(box.min().z(), 100.0, 1e-12);
  EXPECT_NEAR(box.max().z(), 600.0, 1e-12);
  EXPECT_NEAR(box.max().x(), 85.0, 1e-9);

  const Subject mannequin = Parse(R"({"type": "mannequin", "height_mm": 1820,
                                      "chest_girth_mm": 1010})");
  EXPECT_NEAR(mannequin.mesh.Bounds().max().z(), 1820.0, 0.01);
  EXPECT_NEAR(mannequin.metadata.at("chest").at("girth_mm").get<double>(), 1010.0, 1e-6);
}

TEST(SubjectParseTest, ErrorsNameTheKey) {
  EXPECT_EQ(ParseError(R"({"type": "cuboid", "sise_mm": [1, 2, 3]})"),
            "scene.json: subject.sise_mm: unknown key (expected one of: type, size_mm, "
            "center_mm, yaw_deg)");
  EXPECT_EQ(
      ParseError(R"({"type": "sphere"})"),
      "scene.json: subject.type: \"sphere\" is not one of: cuboid, cylinder, mannequin, body, "
      "mesh, none");
  EXPECT_EQ(ParseError(R"({})"), "scene.json: subject.type: missing (expected a string)");
  EXPECT_EQ(ParseError(R"({"type": "cuboid", "size_mm": [100, -1, 300]})"),
            "scene.json: subject.size_mm: every size must be positive");
  EXPECT_EQ(ParseError(R"({"type": "cuboid", "size_mm": [100, 300]})"),
            "scene.json: subject.size_mm: expected an array of 3 numbers");
  EXPECT_EQ(ParseError(R"({"type": "cuboid", "center_mm": [0, 0, 200]})"),
            "scene.json: subject.center_mm: puts the cuboid's underside at z = 41.6 mm; its "
            "tripod needs at least 300 mm");
  EXPECT_EQ(ParseError(R"({"type": "cylinder", "radius_mm": 0})"),
            "scene.json: subject.radius_mm: must be in [1, 2000], got 0");
  EXPECT_EQ(ParseError(R"({"type": "cylinder", "center_mm": [0, 0, 0]})"),
            "scene.json: subject.center_mm: expected an array of 2 numbers");
  EXPECT_EQ(ParseError(R"({"type": "mannequin", "height_mm": "tall"})"),
            "scene.json: subject.height_mm: expected a number");
  EXPECT_EQ(ParseError(R"({"type": "mannequin", "yaw": 3})").substr(0, 45),
            "scene.json: subject.yaw: unknown key (expecte");
  EXPECT_EQ(
      ParseError(R"({"type": "mannequin", "height_mm": 1000, "chest_girth_mm": 500,
                                     "waist_girth_mm": 1800})"),
      "scene.json: subject.waist_girth_mm: too large for height_mm 1000: the arms cannot hang "
      "clear of the torso");
  EXPECT_EQ(ParseError(R"({"type": "none", "radius_mm": 3})"),
            "scene.json: subject.radius_mm: unknown key (expected one of: type)");
  EXPECT_EQ(ParseError(R"({"type": "mesh"})"),
            "scene.json: subject.path: missing (expected a string)");
  EXPECT_EQ(ParseError(R"({"type": "mesh", "path": "a.ply", "scale": 0})"),
            "scene.json: subject.scale: must be in [1e-09, 1e+09], got 0");
}

// ---- Mesh files ----------------------------------------------------------------------

class SubjectMeshFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::path(::testing::TempDir()) /
           ("subjects_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // A tetrahedron with corners (0,0,0), (1,0,0), (0,1,0), (0,0,1), outward winding.
  static constexpr double kCorners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  static constexpr int kFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

  void Write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
  }
  static std::string Obj() {
    std::string s = "# tetrahedron\n";
    for (const auto& c : kCorners) {
      s += "v " + std::to_string(c[0]) + " " + std::to_string(c[1]) + " " + std::to_string(c[2]) +
           "\n";
    }
    for (const auto& f : kFaces) {
      s += "f " + std::to_string(f[0] + 1) + " " + std::to_string(f[1] + 1) + " " +
           std::to_string(f[2] + 1) + "\n";
    }
    return s;
  }
  static std::string Ply() {
    std::string s =
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
        "end_header\n";
    for (const auto& c : kCorners) {
      s += std::to_string(c[0]) + " " + std::to_string(c[1]) + " " + std::to_string(c[2]) + "\n";
    }
    for (const auto& f : kFaces) {
      s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) +
           "\n";
    }
    return s;
  }
  static std::string Stl() {
    std::string s = "solid tetra\n";
    for (const auto& f : kFaces) {
      s += "facet normal 0 0 0\n outer loop\n";
      for (int k : f) {
        s += "  vertex " + std::to_string(kCorners[k][0]) + " " + std::to_string(kCorners[k][1]) +
             " " + std::to_string(kCorners[k][2]) + "\n";
      }
      s += " endloop\nendfacet\n";
    }
    return s + "endsolid tetra\n";
  }

  std::filesystem::path dir_;
};

TEST_F(SubjectMeshFileTest, LoadsEveryFormatWithScaleRotationAndTranslation) {
  Write("tetra.obj", Obj());
  Write("tetra.ply", Ply());
  Write("tetra.stl", Stl());
  // rotation [90, 0, 90]: Rx(90) then Rz(90). Rx(90): (x,y,z) -> (x,-z,y);
  // Rz(90): (x,y,z) -> (-y,x,z). Together (x,y,z) -> (z, x, y); then scale 2, +t.
  auto expected = [](int corner) {
    const double* c = kCorners[corner];
    return Eigen::Vector3d(10 + 2 * c[2], 20 + 2 * c[0], 30 + 2 * c[1]);
  };
  for (const std::string name : {"tetra.obj", "tetra.ply", "tetra.stl"}) {
    SCOPED_TRACE(name);
    const Subject subject = Parse(R"({"type": "mesh", "path": ")" + name +
                                      R"(", "scale": 2, "translation_mm": [10, 20, 30],
                                      "rotation_deg": [90, 0, 90]})",
                                  dir_);
    EXPECT_EQ(subject.type, "mesh");
    ASSERT_EQ(subject.mesh.triangles.size(), 4u);
    for (int t = 0; t < 4; ++t) {
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d& v = subject.mesh.vertices[subject.mesh.triangles[t][k]];
        EXPECT_LT((v - expected(kFaces[t][k])).norm(), 1e-6) << "triangle " << t;
      }
    }
    // A proper rotation and positive scale keep the winding outward: volume 8/6.
    EXPECT_NEAR(SignedVolume(subject.mesh, AllTriangles(subject.mesh)), 8.0 / 6.0, 1e-6);
    EXPECT_EQ(subject.metadata.at("params").at("path"), (dir_ / name).string());
  }
  // An absolute path ignores the base directory.
  const Subject absolute = Parse(
      R"({"type": "mesh", "path": ")" + (dir_ / "tetra.obj").string() + R"("})", "/nonexistent");
  EXPECT_TRUE(absolute.mesh.Bounds().isApprox(
      Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones())));
}

TEST_F(SubjectMeshFileTest, BadFilesNameTheFileAndTheKey) {
  EXPECT_EQ(ParseError(R"({"type": "mesh", "path": "missing.stl"})", dir_),
            "scene.json: subject.path: " + (dir_ / "missing.stl").string() + ": no such file");
  Write("empty.ply", "");
  EXPECT_EQ(ParseError(R"({"type": "mesh", "path": "empty.ply"})", dir_),
            "scene.json: subject.path: " + (dir_ / "empty.ply").string() + ": not a PLY file");
  Write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  EXPECT_EQ(
      ParseError(R"({"type": "mesh", "path": "points.obj"})", dir_),
      "scene.json: subject.path: " + (dir_ / "points.obj").string() + ": mesh has no triangles");
  Write("tetra.off", "OFF\n");
  EXPECT_EQ(ParseError(R"({"type": "mesh", "path": "tetra.off"})", dir_),
            "scene.json: subject.path: " + (dir_ / "tetra.off").string() +
                ": unsupported mesh format \".off\" (expected .ply, .obj or .stl)");
  EXPECT_EQ(ParseError(R"({"type": "mesh", "path": "tetra.obj", "rotation": [0, 0, 0]})", dir_)
                .substr(0, 49),
            "scene.json: subject.rotation: unknown key (expect");
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

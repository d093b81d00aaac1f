// Measurements on the virtual cabinet's exact subject surfaces against the truth its
// subjects work out from their defining shapes (boards/virtual/subjects.h).
#include "host/measurement/measure.h"

#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "boards/virtual/subjects.h"
#include "host/measurement/section.h"

namespace mirrorscan::measurement {
namespace {

namespace vc = virtual_cabinet;

struct Pose {
  std::string name;
  vc::MannequinParams params;
};

vc::MannequinParams Body(double height, double chest, double waist, double hip, double yaw = 0.0,
                         std::optional<double> arm_angle = std::nullopt,
                         Eigen::Vector2d center = Eigen::Vector2d::Zero()) {
  vc::MannequinParams p;
  p.height_mm = height;
  p.chest_girth_mm = chest;
  p.waist_girth_mm = waist;
  p.hip_girth_mm = hip;
  p.yaw_deg = yaw;
  p.arm_angle_deg = arm_angle;
  p.center_mm = center;
  return p;
}

// The sizes and poses docs/measurement.md tabulates (arms raised: below).
std::vector<Pose> Poses() {
  return {{"Default", vc::MannequinParams{}},
          {"Small", Body(1550, 860, 700, 920)},
          {"Tall", Body(1950, 1040, 880, 1040)},
          {"Slim", Body(1700, 880, 680, 900)},
          {"Broad", Body(1800, 1120, 980, 1120)},
          {"Yaw30Offset", Body(1600, 1100, 950, 1050, 30.0, std::nullopt, {50.0, -20.0})},
          {"YawMinus45", Body(1800, 1000, 850, 1020, -45.0)},
          {"ArmsNear15", Body(1750, 960, 800, 1000, 0.0, 15.0)},
          {"ArmsNear20Yaw20", Body(1650, 920, 760, 980, 20.0, 20.0)},
          {"ArmsOut45", Body(1750, 960, 800, 1000, 0.0, 45.0)},
          {"ArmsOut40Yaw90", Body(1700, 940, 780, 990, 90.0, 40.0)}};
}

void PrintTo(const Pose& pose, std::ostream* out) { *out << pose.name; }

class MannequinMeasureTest : public ::testing::TestWithParam<Pose> {};

double Truth(const nlohmann::json& truth, const std::string& key) {
  return truth.at(key).get<double>();
}

void ExpectMeasured(const BodyMeasurements& body, const std::string& name, double truth,
                    double tolerance) {
  const Measurement* m = body.Find(name);
  ASSERT_NE(m, nullptr) << name;
  ASSERT_FALSE(m->withheld) << name << " withheld: " << *m->withheld;
  ASSERT_TRUE(m->value_mm) << name;
  EXPECT_NEAR(*m->value_mm, truth, tolerance) << name << " at z " << m->z_mm.value_or(-1);
  EXPECT_GT(m->confidence, 0.0) << name;
}

TEST_P(MannequinMeasureTest, WithinIsoBoundsOfTheAnalyticTruth) {
  const vc::Subject subject = vc::MakeMannequin(GetParam().params);
  const nlohmann::json& truth = subject.metadata.at("truth");
  const BodyMeasurements body = MeasureBody(subject.mesh);
  ASSERT_TRUE(body.human);
  // Heights and lengths within 2 mm, girths within 3 mm (the issue's bounds).
  ExpectMeasured(body, "stature", Truth(truth, "stature_mm"), 2.0);
  ExpectMeasured(body, "crotch_height", Truth(truth, "crotch_height_mm"), 2.0);
  ExpectMeasured(body, "shoulder_breadth", Truth(truth, "shoulder_breadth_mm"), 2.0);
  for (const char* side : {"left", "right"}) {
    ExpectMeasured(body, std::string("arm_length_") + side, Truth(truth, "arm_length_mm"), 2.0);
    ExpectMeasured(body, std::string("thigh_girth_") + side, Truth(truth, "thigh_girth_mm"), 3.0);
    ExpectMeasured(body, std::string("upper_arm_girth_") + side, Truth(truth, "upper_arm_girth_mm"),
                   3.0);
  }
  for (const char* girth : {"chest", "waist", "hip", "neck"}) {
    ExpectMeasured(body, std::string(girth) + "_girth",
                   Truth(truth, std::string(girth) + "_girth_mm"), 3.0);
  }
  // A convex section's followed contour is its tape girth.
  const Measurement* waist = body.Find("waist_girth");
  ASSERT_TRUE(waist->contour_mm);
  EXPECT_NEAR(*waist->contour_mm, *waist->value_mm, 0.5);
  ASSERT_TRUE(body.stature_mm);
  EXPECT_NEAR(*body.stature_mm, Truth(truth, "stature_mm"), 2.0);
}

TEST_P(MannequinMeasureTest, GirthAtAnyHeightMatchesTheTruthSection) {
  const vc::MannequinParams& p = GetParam().params;
  const vc::Subject subject = vc::MakeMannequin(p);
  MeasureOptions options;
  std::vector<std::pair<double, vc::GirthTruth>> expected;
  for (double fraction = 0.05; fraction < 0.95; fraction += 0.0137) {
    const double z = fraction * p.height_mm;
    const std::optional<vc::GirthTruth> truth = vc::MannequinGirthTruth(p, z);
    // Not within 3 mm of the crotch, where a section changes from legs to torso.
    if (!truth ||
        std::abs(z - subject.metadata.at("truth").at("crotch_height_mm").get<double>()) < 3.0)
      continue;
    options.girth_at_mm.push_back(z);
    expected.emplace_back(z, *truth);
  }
  ASSERT_GT(expected.size(), 20u);
  const BodyMeasurements body = MeasureBody(subject.mesh, options);
  for (const auto& [z, truth] : expected) {
    SCOPED_TRACE("z " + std::to_string(z) + " " + truth.part);
    bool seen = false;
    for (const SliceGirth& s : body.slices) {
      if (s.z_mm != z ||
          (s.part != truth.part && !(truth.part == "left_leg" && s.part == "right_leg")))
        continue;
      seen = true;
      ASSERT_FALSE(s.withheld) << *s.withheld;
      EXPECT_NEAR(*s.girth_mm, truth.girth_mm, 3.0) << s.part;
    }
    EXPECT_TRUE(seen);
  }
}

std::string PoseName(const ::testing::TestParamInfo<Pose>& info) { return info.param.name; }

INSTANTIATE_TEST_SUITE_P(Mannequins, MannequinMeasureTest, ::testing::ValuesIn(Poses()), PoseName);

TEST(MannequinMeasureTest, RaisedArmsGiveTorsoAndHeightsButWithholdTheArms) {
  const vc::MannequinParams p = Body(1750, 960, 800, 1000, 10.0, 120.0);
  const vc::Subject subject = vc::MakeMannequin(p);
  const nlohmann::json& truth = subject.metadata.at("truth");
  const BodyMeasurements body = MeasureBody(subject.mesh);
  ASSERT_TRUE(body.human);
  ExpectMeasured(body, "stature", Truth(truth, "stature_mm"), 2.0);
  ExpectMeasured(body, "crotch_height", Truth(truth, "crotch_height_mm"), 2.0);
  for (const char* girth : {"chest", "waist", "hip", "neck"}) {
    ExpectMeasured(body, std::string(girth) + "_girth",
                   Truth(truth, std::string(girth) + "_girth_mm"), 3.0);
  }
  for (const char* name : {"arm_length_left", "upper_arm_girth_right", "shoulder_breadth"}) {
    const Measurement* m = body.Find(name);
    ASSERT_NE(m, nullptr);
    EXPECT_FALSE(m->value_mm) << name;
    ASSERT_TRUE(m->withheld) << name;
    EXPECT_NE(m->withheld->find("raised"), std::string::npos) << *m->withheld;
  }
}

// Arms hanging at 5 degrees touch the torso from the chest up: the chest girth is
// withheld, the waist and hip below the touch are not.
TEST(MannequinMeasureTest, ArmsAgainstTheTorsoWithholdItsGirths) {
  const vc::Subject subject = vc::MakeMannequin(Body(1750, 960, 800, 1000, 0.0, 5.0));
  const nlohmann::json& truth = subject.metadata.at("truth");
  const BodyMeasurements body = MeasureBody(subject.mesh);
  ASSERT_TRUE(body.human);
  for (const char* name : {"chest_girth"}) {
    const Measurement* m = body.Find(name);
    ASSERT_NE(m, nullptr);
    EXPECT_FALSE(m->value_mm) << name << " = " << m->value_mm.value_or(0);
    ASSERT_TRUE(m->withheld) << name;
    EXPECT_NE(m->withheld->find("arm"), std::string::npos) << *m->withheld;
  }
  // What the arms do not touch is still measured.
  ExpectMeasured(body, "stature", 1750.0, 2.0);
  ExpectMeasured(body, "waist_girth", Truth(truth, "waist_girth_mm"), 3.0);
  ExpectMeasured(body, "hip_girth", Truth(truth, "hip_girth_mm"), 3.0);
}

// The mesh without the triangles whose centre lies within `radius` of `centre`.
TriangleMesh CutOut(const TriangleMesh& mesh, const Eigen::Vector3d& centre, double radius) {
  TriangleMesh cut;
  cut.vertices = mesh.vertices;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d c = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3;
    if ((c - centre).norm() >= radius) cut.triangles.push_back(t);
  }
  return cut;
}

// The mannequin with the front of its waist cut out (a ball of `waist_hole_mm` round)
// and the top of its head (25 mm).
TriangleMesh MannequinWithHoles(const vc::Subject& subject, double waist_hole_mm) {
  const nlohmann::json& truth = subject.metadata.at("truth");
  const double waist_z = truth.at("waist_z_mm").get<double>();
  const double b = subject.metadata.at("waist").at("semi_axes_mm")[1].get<double>();
  const TriangleMesh waist_cut =
      CutOut(subject.mesh, Eigen::Vector3d(0.0, -b, waist_z), waist_hole_mm);
  return CutOut(waist_cut, Eigen::Vector3d(0.0, 0.0, 1750.0), 25.0);
}

// A hole too wide to bridge withholds the measurements whose sections cross it.
TEST(MannequinMeasureTest, HolesWithholdWhatTheyCross) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  const nlohmann::json& truth = subject.metadata.at("truth");
  const TriangleMesh mesh = MannequinWithHoles(subject, 30.0);  // ~60 mm across the waist
  ASSERT_LT(mesh.triangles.size(), subject.mesh.triangles.size());
  const BodyMeasurements body = MeasureBody(mesh);
  const Measurement* waist = body.Find("waist_girth");
  ASSERT_NE(waist, nullptr);
  EXPECT_FALSE(waist->value_mm);
  ASSERT_TRUE(waist->withheld);
  EXPECT_NE(waist->withheld->find("hole"), std::string::npos) << *waist->withheld;
  // Far from the holes, the numbers stand.
  ExpectMeasured(body, "hip_girth", truth.at("hip_girth_mm").get<double>(), 3.0);
  ExpectMeasured(body, "crotch_height", truth.at("crotch_height_mm").get<double>(), 2.0);
}

// The mesh without the triangles whose centre is above `z` and behind `y` (in front of
// which the camera sees): the back of the head above the mirrors' reach.
TriangleMesh CutBehind(const TriangleMesh& mesh, double y, double z) {
  TriangleMesh cut;
  cut.vertices = mesh.vertices;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d c = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3;
    if (c.y() <= y || c.z() <= z) cut.triangles.push_back(t);
  }
  return cut;
}

// Holes at the top of the head, as scans leave them, leave the highest vertex on a rim
// below the true top: the top (10 and 40 mm round), and with it the back above the
// mirrors (from 30 mm below the top). The stature comes from the cap below them, within
// the analytic stature and with a lower confidence; deeper, it is withheld.
TEST(MannequinMeasureTest, AHoleAtTheTopOfTheHeadIsClosedFromTheCapBelowIt) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  const double stature = Truth(subject.metadata.at("truth"), "stature_mm");
  const TriangleMesh mesh = subject.mesh;
  for (const bool back_open : {false, true}) {
    for (const double hole_mm : {10.0, 40.0}) {
      TriangleMesh holed = CutOut(mesh, Eigen::Vector3d(0, 0, stature), hole_mm);
      if (back_open) holed = CutBehind(holed, -7.0, stature - 30.0);
      const BodyMeasurements body = MeasureBody(holed);
      const Measurement* m = body.Find("stature");
      ASSERT_NE(m, nullptr);
      ASSERT_FALSE(m->withheld) << hole_mm << ": " << m->withheld.value_or("");
      ASSERT_TRUE(body.stature_mm);
      EXPECT_NEAR(*body.stature_mm, stature, 0.3) << hole_mm << (back_open ? ", back open" : "");
      EXPECT_GT(m->confidence, 0.5);
      EXPECT_LT(m->confidence, 1.0);
    }
  }
  // A trimmed mesh's border droops (Poisson's surface sags where the points end): with the
  // rim's vertices 1.5 mm low the fit keeps clear of them (planted, without the clearance
  // the stature is 1.0 mm low).
  {
    TriangleMesh ragged =
        CutBehind(CutOut(mesh, Eigen::Vector3d(0, 0, stature), 40.0), -7.0, stature - 30.0);
    std::map<std::pair<int, int>, int> edges;
    for (const Eigen::Vector3i& t : ragged.triangles) {
      for (int k = 0; k < 3; ++k) ++edges[std::minmax(t[k], t[(k + 1) % 3])];
    }
    std::set<int> rim;
    for (const auto& [edge, count] : edges) {
      if (count == 1 && ragged.vertices[edge.first].z() > stature - 100.0) {
        rim.insert(edge.first);
        rim.insert(edge.second);
      }
    }
    for (int v : rim) ragged.vertices[v].z() -= 1.5;
    const BodyMeasurements body = MeasureBody(ragged);
    ASSERT_TRUE(body.stature_mm) << body.Find("stature")->withheld.value_or("");
    EXPECT_NEAR(*body.stature_mm, stature, 0.3) << "ragged rim";
  }
  // A ball of 70 mm round the top opens the head some 37 mm down: further than it may
  // extrapolate.
  const BodyMeasurements deep = MeasureBody(CutOut(mesh, Eigen::Vector3d(0, 0, stature), 70.0));
  EXPECT_FALSE(deep.stature_mm) << *deep.stature_mm << " confidence "
                                << deep.Find("stature")->confidence;
  const Measurement* m = deep.Find("stature");
  ASSERT_TRUE(m && m->withheld);
  EXPECT_NE(m->withheld->find("top of the head"), std::string::npos) << *m->withheld;
}

// What a hole hides can only add to the hull of what was seen: a hole in the shoulder's
// top beside the neck, whose seen sections are far longer round than the neck, does not
// withhold the neck's (smallest) girth; a hole in the waist's own outline still withholds
// the waist (HolesWithholdWhatTheyCross).
TEST(MannequinMeasureTest, AHoleThatCannotHideASmallerGirthDoesNotWithholdIt) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  const BodyMeasurements body =
      MeasureBody(CutOut(subject.mesh, Eigen::Vector3d(85, 0, 1475), 25.0));
  ExpectMeasured(body, "neck_girth", Truth(subject.metadata.at("truth"), "neck_girth_mm"), 3.0);
  EXPECT_LT(body.Find("neck_girth")->confidence, 1.0);  // beside a hole all the same
}

// A small hole is bridged along the section's own curve: the waist across a hole of up to
// 36 mm comes out at the analytic truth, with a confidence that says part of it was not
// seen.
TEST(MannequinMeasureTest, ASmallHoleIsBridged) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  const BodyMeasurements holed = MeasureBody(MannequinWithHoles(subject, 18.0));
  const Measurement* h = holed.Find("waist_girth");
  ASSERT_TRUE(h);
  ASSERT_TRUE(h->value_mm) << h->withheld.value_or("");
  EXPECT_NEAR(*h->value_mm, Truth(subject.metadata.at("truth"), "waist_girth_mm"), 0.1);
  EXPECT_LT(h->confidence, 0.99);
  EXPECT_GT(h->confidence, 0.9);
}

// A line through a hole crosses nothing there: with the arm's end or the shoulder cut
// open (as a scan leaves them), a crossing further on would be taken for the landmark.
TEST(MannequinMeasureTest, HolesAtAnArmsEndsWithholdItsLandmarks) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  const nlohmann::json& truth = subject.metadata.at("truth");
  const TriangleMesh whole = subject.mesh;
  const BodyMeasurements exact = MeasureBody(whole);
  const Eigen::Vector3d* wrist = nullptr;
  const Eigen::Vector3d* shoulder = nullptr;
  for (const Landmark& l : exact.landmarks) {
    if (l.name == "wrist_left") wrist = &l.point_mm;
    if (l.name == "shoulder_left") shoulder = &l.point_mm;
  }
  ASSERT_TRUE(wrist && shoulder);
  struct Case {
    Eigen::Vector3d centre;
    const char* reason;
  };
  for (const Case& c :
       {Case{*wrist, "the wrist is not seen"}, Case{*shoulder, "the shoulder point is not seen"}}) {
    const BodyMeasurements body = MeasureBody(CutOut(whole, c.centre, 30.0));
    for (const char* name : {"arm_length_left", "upper_arm_girth_left", "shoulder_breadth"}) {
      const Measurement* m = body.Find(name);
      ASSERT_NE(m, nullptr);
      EXPECT_FALSE(m->value_mm) << name << " " << c.reason;
      ASSERT_TRUE(m->withheld) << name;
      EXPECT_NE(m->withheld->find(c.reason), std::string::npos) << name << ": " << *m->withheld;
    }
    ExpectMeasured(body, "arm_length_right", Truth(truth, "arm_length_mm"), 2.0);
  }
}

// Turned 45°, one leg stands behind the other as the camera sees them and a scan leaves the
// side of one that faces the other open, from the ankle to the thigh: an open chain beside
// the other leg's closed outline. It is still a leg (an open chain is grouped with what lies
// within 20 mm of its outline, not of its box: legs side by side at 45° have overlapping
// boxes): the body is human, and what the hole does not cross stands.
TEST(MannequinMeasureTest, ALegOpenOnTheSideFacingTheOtherIsStillALeg) {
  vc::MannequinParams params;
  params.yaw_deg = -45.0;
  const vc::Subject subject = vc::MakeMannequin(params);
  const nlohmann::json& truth = subject.metadata.at("truth");
  TriangleMesh mesh = subject.mesh;
  // The legs' centres and radius from the exact section at 450 mm.
  const Section legs = Slicer(mesh).AtHeight(450.0);
  ASSERT_GE(legs.parts.size(), 2u);
  const Eigen::Vector2d a = legs.parts[0].centroid, b = legs.parts[1].centroid;
  const double radius = legs.parts[1].tape_mm / (2.0 * std::numbers::pi);
  const Eigen::Vector2d inner = b + radius * (a - b).normalized();
  for (double z = 120.0; z <= 620.0; z += 25.0) {
    mesh = CutOut(mesh, Eigen::Vector3d(inner.x(), inner.y(), z), 0.6 * radius);
  }
  const Section open = Slicer(mesh).AtHeight(450.0, /*join_holes=*/false);
  int open_chains = 0;
  for (const SectionLoop& loop : open.loops) open_chains += loop.closed ? 0 : 1;
  ASSERT_GE(open_chains, 1);  // the cut opened the leg

  const BodyMeasurements body = MeasureBody(mesh);
  EXPECT_TRUE(body.human);
  // The crotch is withheld while a hole crosses a leg where the legs are first found; the
  // hip above it is searched from the crotch the legs give, so it stands only on a right one.
  const Measurement* crotch = body.Find("crotch_height");
  ASSERT_TRUE(crotch && crotch->withheld);
  EXPECT_NE(crotch->withheld->find("a hole crosses the legs"), std::string::npos)
      << *crotch->withheld;
  for (const char* girth : {"hip", "waist", "chest"}) {
    ExpectMeasured(body, std::string(girth) + "_girth",
                   Truth(truth, std::string(girth) + "_girth_mm"), 3.0);
  }
}

void ExpectAllWithheld(const vc::Subject& subject) {
  MeasureOptions options;
  options.girth_at_mm = {500.0};
  const BodyMeasurements body = MeasureBody(subject.mesh, options);
  EXPECT_FALSE(body.human);
  EXPECT_FALSE(body.stature_mm);
  ASSERT_GE(body.measurements.size(), 10u);
  for (const Measurement& m : body.measurements) {
    EXPECT_FALSE(m.value_mm) << m.name;
    ASSERT_TRUE(m.withheld) << m.name;
    EXPECT_NE(m.withheld->find("not a human body"), std::string::npos) << *m.withheld;
  }
}

TEST(NonHumanMeasureTest, CuboidOnItsTripodIsNotMeasured) {
  ExpectAllWithheld(vc::MakeCuboidOnTripod(vc::CuboidParams{}));
}

TEST(NonHumanMeasureTest, CylinderIsNotMeasuredButItsGirthIsTaken) {
  vc::CylinderParams p;
  ExpectAllWithheld(vc::MakeCylinder(p));
  MeasureOptions options;
  options.girth_at_mm = {900.0};
  const BodyMeasurements body = MeasureBody(vc::MakeCylinder(p).mesh, options);
  ASSERT_EQ(body.slices.size(), 1u);
  ASSERT_TRUE(body.slices[0].girth_mm);
  EXPECT_NEAR(*body.slices[0].girth_mm, 2.0 * std::numbers::pi * p.radius_mm, 0.1);
}

TEST(MeasureJsonTest, ShapeOfTheIssue) {
  const vc::Subject subject = vc::MakeMannequin(vc::MannequinParams{});
  MeasureOptions options;
  options.girth_at_mm = {1000.0};
  const nlohmann::json json = ToJson(MeasureBody(subject.mesh, options));
  EXPECT_TRUE(json.at("stature_mm").is_number());
  for (const nlohmann::json& m : json.at("measurements")) {
    for (const char* key : {"name", "value_mm", "z_mm", "confidence", "withheld"}) {
      EXPECT_TRUE(m.contains(key)) << key;
    }
  }
  ASSERT_EQ(json.at("slices").size(), 1u);
  EXPECT_EQ(json.at("slices")[0].at("z_mm"), 1000.0);
  EXPECT_TRUE(json.at("slices")[0].at("girth_mm").is_number());
  EXPECT_TRUE(json.at("slices")[0].at("contour_mm").is_number());
}

}  // namespace
}  // namespace mirrorscan::measurement

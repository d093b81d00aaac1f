#include "host/measurement/section.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace mirrorscan::measurement {
namespace {

// An L-shaped prism from z = 0 to 50 (outward normals): its outline is 400 mm, and a
// tape round it spans the hollow: 100 + 40 + 60 sqrt 2 + 40 + 100 mm.
TriangleMesh LPrism() {
  const std::vector<Eigen::Vector2d> outline = {{0, 0},   {100, 0},  {100, 40},
                                                {40, 40}, {40, 100}, {0, 100}};
  TriangleMesh mesh;
  const int n = static_cast<int>(outline.size());
  for (double z : {0.0, 50.0}) {
    for (const Eigen::Vector2d& p : outline) mesh.vertices.emplace_back(p.x(), p.y(), z);
  }
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    mesh.triangles.emplace_back(i, j, n + j);
    mesh.triangles.emplace_back(i, n + j, n + i);
  }
  for (int i = 1; i + 1 < n; ++i) {  // fans from corner 0: inside the L for this outline
    mesh.triangles.emplace_back(0, i + 1, i);
    mesh.triangles.emplace_back(n, n + i, n + i + 1);
  }
  return mesh;
}

TEST(SectionTest, TapeSpansTheHollowAndTheContourFollowsIt) {
  const Slicer slicer(LPrism());
  const Section s = slicer.AtHeight(25.0);
  ASSERT_EQ(s.loops.size(), 1u);
  EXPECT_TRUE(s.loops[0].closed);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_NEAR(s.parts[0].contour_mm, 400.0, 1e-9);
  EXPECT_NEAR(s.parts[0].tape_mm, 280.0 + 60.0 * std::sqrt(2.0), 1e-3);
  EXPECT_NEAR(s.parts[0].area_mm2, 100.0 * 100.0 - 0.5 * 60.0 * 60.0, 0.5);
  EXPECT_FALSE(s.parts[0].has_hole);
}

TEST(SectionTest, AVertexOnThePlaneCountsAsAbove) {
  // The plane an instant lower: at the top face the prism is still cut, at the bottom not.
  const Slicer slicer(LPrism());
  EXPECT_EQ(slicer.AtHeight(50.0).parts.size(), 1u);
  EXPECT_TRUE(slicer.AtHeight(0.0).parts.empty());
}

TEST(SectionTest, AMissingFaceLeavesAnOpenChainAndMarksAHole) {
  TriangleMesh mesh = LPrism();
  mesh.triangles.erase(mesh.triangles.begin(), mesh.triangles.begin() + 2);  // side 0-1
  const Slicer slicer(mesh);
  const Section s = slicer.AtHeight(25.0);
  ASSERT_EQ(s.loops.size(), 1u);
  EXPECT_FALSE(s.loops[0].closed);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_TRUE(s.parts[0].has_hole);
}

// A closed cylinder of radius `radius` round the vertical line x = `centre_x`, y = 0 from
// z = 0 to 100, 256 sides, with the side faces whose middle lies within `gap_deg` / 2 of
// the direction `gap_towards_deg` (from +x) left out between z 20 and 80.
TriangleMesh CylinderWithAGap(double gap_deg, double radius = 100.0, double centre_x = 0.0,
                              double gap_towards_deg = 0.0) {
  constexpr int kSides = 256;
  TriangleMesh mesh;
  const std::vector<double> heights = {0.0, 20.0, 80.0, 100.0};
  for (double z : heights) {
    for (int i = 0; i < kSides; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kSides;
      mesh.vertices.emplace_back(centre_x + radius * std::cos(a), radius * std::sin(a), z);
    }
  }
  for (int ring = 0; ring + 1 < static_cast<int>(heights.size()); ++ring) {
    for (int i = 0; i < kSides; ++i) {
      const int j = (i + 1) % kSides;
      double middle = std::remainder(360.0 * (i + 0.5) / kSides - gap_towards_deg, 360.0);
      if (ring == 1 && std::abs(middle) < gap_deg / 2.0) continue;
      const int a = ring * kSides + i, b = ring * kSides + j;
      mesh.triangles.emplace_back(a, b, b + kSides);
      mesh.triangles.emplace_back(a, b + kSides, a + kSides);
    }
  }
  return mesh;
}

TEST(SectionTest, AHoleIsBridgedAlongTheOutlinesOwnCurve) {
  // A quarter of the circle missing: the bridge follows the arc, where the chord across
  // the gap would make the tape 2 pi r - (pi / 2 - sqrt 2) r = 612.6 mm.
  const Slicer slicer(CylinderWithAGap(90.0));
  const Section s = slicer.AtHeight(50.0);
  ASSERT_EQ(s.parts.size(), 1u);
  const SectionPart& part = s.parts[0];
  EXPECT_TRUE(part.has_hole);
  ASSERT_TRUE(part.bridged);
  const double polygon = 256 * 2.0 * 100.0 * std::sin(std::numbers::pi / 256);
  EXPECT_NEAR(part.tape_mm, polygon, 0.1);
  EXPECT_NEAR(part.contour_mm, polygon, 0.1);
  EXPECT_NEAR(part.largest_bridge_mm, 100.0 * std::sqrt(2.0), 1.0);
  // A section through the whole side has no hole and no bridge.
  const Section whole = slicer.AtHeight(10.0);
  ASSERT_EQ(whole.parts.size(), 1u);
  EXPECT_FALSE(whole.parts[0].has_hole);
  EXPECT_FALSE(whole.parts[0].bridged);
  EXPECT_EQ(whole.parts[0].bridged_mm, 0.0);
}

TEST(SectionTest, OpenSidesFacingEachOtherAreNotJoined) {
  // Two limbs 30 mm apart, each open on the side facing the other (an arm beside the
  // torso, the thighs below the crotch): their ends point towards each other, but a join
  // would bend against both. Each is bridged round its own side instead.
  TriangleMesh mesh = CylinderWithAGap(90.0, 50.0, 0.0, 0.0);
  const TriangleMesh other = CylinderWithAGap(90.0, 50.0, 130.0, 180.0);
  const int offset = static_cast<int>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (const Eigen::Vector3i& t : other.triangles) {
    mesh.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
  const Section s = Slicer(mesh).AtHeight(50.0);
  ASSERT_EQ(s.parts.size(), 2u);
  const double polygon = 256 * 2.0 * 50.0 * std::sin(std::numbers::pi / 256);
  for (const SectionPart& part : s.parts) {
    EXPECT_TRUE(part.bridged);
    EXPECT_NEAR(part.tape_mm, polygon, 0.1);
    EXPECT_NEAR(part.largest_bridge_mm, 50.0 * std::sqrt(2.0), 1.0);
  }
}

TEST(SectionTest, TiltedPlaneThroughACube) {
  // The plane x + z = 95 through the L prism's lower bar cuts a rectangle 40 wide (y 0..40)
  // and 50 sqrt 2 long: perimeter 80 + 100 sqrt 2.
  const Slicer slicer(LPrism());
  const Section s = slicer.ByPlane(Eigen::Vector3d(95, 20, 0), Eigen::Vector3d(1, 0, 1));
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_NEAR(s.parts[0].tape_mm, 80.0 + 100.0 * std::sqrt(2.0), 1e-3);
}

TEST(SectionTest, LineCrossingsSayWhereTheLineEntersAndLeaves) {
  const TriangleMesh mesh = LPrism();
  const std::vector<LineCrossing> c =
      CrossLine(mesh, Eigen::Vector3d(50, 10, 25), Eigen::Vector3d(1, 0, 0));
  ASSERT_EQ(c.size(), 2u);
  EXPECT_NEAR(c[0].t, -50.0, 1e-9);
  EXPECT_EQ(c[0].sign, -1);  // enters
  EXPECT_NEAR(c[1].t, 50.0, 1e-9);
  EXPECT_EQ(c[1].sign, +1);  // leaves
}

TEST(SectionTest, WeldingJoinsTheCornersOfSeparateTriangles) {
  TriangleMesh soup;
  const TriangleMesh mesh = LPrism();
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const int base = static_cast<int>(soup.vertices.size());
    for (int k = 0; k < 3; ++k) soup.vertices.push_back(mesh.vertices[t[k]]);
    soup.triangles.emplace_back(base, base + 1, base + 2);
  }
  const Slicer slicer(WeldVertices(soup));
  EXPECT_EQ(slicer.mesh().vertices.size(), mesh.vertices.size());
  const Section s = slicer.AtHeight(10.0);
  ASSERT_EQ(s.loops.size(), 1u);
  EXPECT_TRUE(s.loops[0].closed);
}

}  // namespace
}  // namespace mirrorscan::measurement

#include "host/meshing/meshing.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "host/meshing/test_clouds.h"

namespace mirrorscan::meshing {
namespace {

// A sphere of radius r about c sampled on a Fibonacci lattice, optionally without the cap
// above polar angle `cap_rad` (measured from +z), with radial noise.
PointCloud SampleSphere(double radius, const Eigen::Vector3d& center, int count,
                        double cap_rad = 0.0, double noise_mm = 0.0) {
  PointCloud cloud;
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, noise_mm);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    if (std::acos(z) < cap_rad) continue;
    const double r = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d n(r * std::cos(golden * i), r * std::sin(golden * i), z);
    CloudPoint& point = cloud.points.emplace_back();
    point.point_in_world =
        (center + n * (radius + (noise_mm > 0 ? noise(random) : 0.0))).cast<float>();
    point.normal = n.cast<float>();
  }
  return cloud;
}

MeshingOptions SmallOptions() {
  MeshingOptions options;
  options.voxel_mm = 0.0;
  options.depth = 7;
  options.min_points = 500;
  return options;
}

TEST(FindHoles, SquareHasOneHoleOfItsPerimeter) {
  TriangleMesh square;
  square.vertices = {{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  const HoleReport report = FindHoles(square);
  ASSERT_EQ(report.count(), 1);
  EXPECT_DOUBLE_EQ(report.largest_perimeter_mm(), 40.0);
  EXPECT_EQ(report.holes[0].edges, 4);
  EXPECT_EQ(report.open_boundary_edges, 0);
}

TEST(FindHoles, ClosedTetrahedronHasNone) {
  TriangleMesh tetrahedron;
  tetrahedron.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  tetrahedron.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  EXPECT_EQ(FindHoles(tetrahedron).count(), 0);
  EXPECT_TRUE(ComputeStats(tetrahedron).watertight);
  EXPECT_NEAR(ComputeStats(tetrahedron).volume_mm3, 1.0 / 6.0, 1e-12);
}

TEST(MeshCloud, SphereIsClosedAndOnItsRadius) {
  const Eigen::Vector3d center(10, -20, 500);
  const MeshingResult result = MeshCloud(SampleSphere(100.0, center, 20000), SmallOptions());
  EXPECT_EQ(result.holes.count(), 0);
  EXPECT_TRUE(result.stats.watertight);
  double worst = 0.0;
  for (const Eigen::Vector3d& v : result.mesh.vertices) {
    worst = std::max(worst, std::abs((v - center).norm() - 100.0));
  }
  // Depth 7 over a 220 mm cube: 1.7 mm cells.
  EXPECT_LT(worst, 0.3);
  EXPECT_NEAR(result.stats.area_mm2, 4 * M_PI * 100.0 * 100.0, 0.01 * 4 * M_PI * 1e4);
  EXPECT_NEAR(result.stats.volume_mm3, 4.0 / 3.0 * M_PI * 1e6, 0.01 * 4.0 / 3.0 * M_PI * 1e6);
}

TEST(MeshCloud, MissingCapIsTrimmedToOneHole) {
  // No points within 40° of the pole: Poisson closes the cap, the trim opens it again
  // a little beyond the data's edge.
  const double cap = 40.0 * M_PI / 180.0;
  const Eigen::Vector3d center(0, 0, 300);
  const MeshingResult result =
      MeshCloud(SampleSphere(100.0, center, 20000, cap, 0.1), SmallOptions());
  ASSERT_EQ(result.holes.count(), 1);
  EXPECT_GT(result.trimmed_far, 0);
  // The data edge's circle is 2π·100·sin 40° = 404 mm round; the trim leaves up to
  // trim_distance_mm (5 mm, ~3° of arc) beyond it, and the loop follows mesh edges, which
  // zigzag about the circle (up to ~15 % longer at these 1.7 mm cells).
  const double data_edge = 2 * M_PI * 100.0 * std::sin(cap);
  EXPECT_LT(result.holes.largest_perimeter_mm(), 1.15 * data_edge);
  EXPECT_GT(result.holes.largest_perimeter_mm(), 0.85 * data_edge);
  EXPECT_NEAR(result.holes.holes[0].centroid.z(), 300 + 100.0 * std::cos(cap), 5.0);
  EXPECT_FALSE(result.stats.watertight);
}

TEST(MeshCloud, WatertightKeepsTheClosedSurface) {
  MeshingOptions options = SmallOptions();
  options.watertight = true;
  const MeshingResult result =
      MeshCloud(SampleSphere(100.0, {0, 0, 300}, 20000, 40.0 * M_PI / 180.0), options);
  EXPECT_EQ(result.holes.count(), 0);
  EXPECT_TRUE(result.stats.watertight);
  EXPECT_EQ(result.stats.components, 1);
}

TEST(MeshCloud, SameCloudGivesTheSameMesh) {
  const PointCloud cloud = SampleSphere(100.0, {0, 0, 300}, 20000, 0.7, 0.2);
  const MeshingResult first = MeshCloud(cloud, SmallOptions());
  for (int run = 0; run < 3; ++run) {
    const MeshingResult again = MeshCloud(cloud, SmallOptions());
    ASSERT_EQ(again.mesh.vertices, first.mesh.vertices);
    ASSERT_EQ(again.mesh.triangles, first.mesh.triangles);
  }
}

TEST(MeshCloud, RefusesWhatCannotBeABody) {
  EXPECT_THROW(MeshCloud(PointCloud{}, SmallOptions()), MeshingError);
  PointCloud sphere = SampleSphere(100.0, {0, 0, 300}, 20000);
  // Only what faces the camera (-y): one view.
  PointCloud front;
  for (const CloudPoint& point : sphere.points) {
    if (point.normal.y() < -0.3) front.points.push_back(point);
  }
  try {
    MeshCloud(front, SmallOptions());
    FAIL() << "a one-view cloud was meshed";
  } catch (const MeshingError& e) {
    EXPECT_NE(std::string(e.what()).find("does not go round a body"), std::string::npos)
        << e.what();
  }
  // Without normals (another program's cloud) nothing orients the surface.
  PointCloud no_normals = sphere;
  for (CloudPoint& point : no_normals.points) point.normal.setZero();
  EXPECT_THROW(MeshCloud(no_normals, SmallOptions()), MeshingError);
  MeshingOptions bad = SmallOptions();
  bad.threads = 0;
  EXPECT_THROW(MeshCloud(sphere, bad), std::invalid_argument);
}

// The mannequin's truth: the virtual cabinet's exact laser-lit stripe points over the
// whole sweep (what the cameras can see and the lasers reach), with the subject's
// surface normals and 0.2 mm of noise along them.
class MannequinMesh : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    truth_ = new testing_clouds::TruthCloud(testing_clouds::MannequinTruthCloud(0.2, 1));
    MeshingOptions options;
    result_ = new MeshingResult(MeshCloud(truth_->cloud, options));
  }
  static void TearDownTestSuite() {
    delete result_;
    delete truth_;
  }
  static testing_clouds::TruthCloud* truth_;
  static MeshingResult* result_;
};
testing_clouds::TruthCloud* MannequinMesh::truth_ = nullptr;
MeshingResult* MannequinMesh::result_ = nullptr;

double Quantile(std::vector<float> values, double q) {
  const size_t k = static_cast<size_t>(q * (values.size() - 1));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

TEST_F(MannequinMesh, MeshLiesOnTheTruthSurface) {
  const std::vector<float> distance =
      testing_clouds::DistancesTo(truth_->surface, result_->mesh.vertices);
  const double mean = std::accumulate(distance.begin(), distance.end(), 0.0) / distance.size();
  const double p95 = Quantile(distance, 0.95);
  RecordProperty("mean_mm", std::to_string(mean));
  RecordProperty("p95_mm", std::to_string(p95));
  std::printf("mesh to truth: mean %.3f mm, p95 %.3f mm, max %.3f mm (%zu vertices, depth %d)\n",
              mean, p95, *std::max_element(distance.begin(), distance.end()), distance.size(),
              result_->depth);
  EXPECT_LE(mean, 0.5);
  EXPECT_LE(p95, 1.5);
}

TEST_F(MannequinMesh, CoversWhatTheCabinetSees) {
  const std::vector<float> distance =
      testing_clouds::DistancesTo(result_->mesh, truth_->exact_points);
  const double within =
      std::count_if(distance.begin(), distance.end(), [](float d) { return d <= 2.0f; }) /
      static_cast<double>(distance.size());
  std::printf("truth stripe points within 2 mm of the mesh: %.2f %%\n", 100 * within);
  EXPECT_GE(within, 0.95);
}

TEST_F(MannequinMesh, ReportsTheUnseenRegionsAsHoles) {
  std::printf("holes: %d, largest perimeter %.0f mm\n", result_->holes.count(),
              result_->holes.largest_perimeter_mm());
  EXPECT_GT(result_->holes.count(), 0);
  EXPECT_GT(result_->trimmed_far, 0);
  // Mesh bounds within the body's (feet on the floor, head at 1750 mm).
  EXPECT_GT(result_->stats.bounds.min().z(), -5.0);
  EXPECT_LT(result_->stats.bounds.max().z(), 1755.0);
}

}  // namespace
}  // namespace mirrorscan::meshing

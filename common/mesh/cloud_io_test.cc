#include "common/mesh/cloud_io.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;

class CloudIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("cloud_io_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(CloudIoTest, WhatIsWrittenComesBackWhole) {
  PointCloud cloud;
  for (int i = 0; i < 5; ++i) {
    CloudPoint p;
    p.point_in_world = Eigen::Vector3f(i, 2.5f * i, -1.0f);
    p.normal = Eigen::Vector3f(0, 0, 1);
    p.camera = static_cast<uint8_t>(i % 2);
    p.view = static_cast<PointView>(i % 5);
    p.laser = static_cast<uint8_t>(i % 3);
    p.frame = 1000u + i;
    p.u = 3.0f * i;
    p.v = 0.25f * i;
    p.confidence = 0.1f * i;
    p.rule = static_cast<DecidedBy>(i % 5);
    cloud.points.push_back(p);
  }
  const fs::path file = dir_ / "points.ply";
  WritePointCloud(file, cloud);
  EXPECT_EQ(fs::file_size(file), 496u + 5 * 44);  // the header, then 44 bytes a point
  const PointCloud back = ReadPointCloud(file, /*require_normals=*/true);
  ASSERT_EQ(back.points.size(), cloud.points.size());
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const CloudPoint &a = back.points[i], &b = cloud.points[i];
    EXPECT_EQ(a.point_in_world, b.point_in_world);
    EXPECT_EQ(a.normal, b.normal);
    EXPECT_EQ(a.camera, b.camera);
    EXPECT_EQ(a.view, b.view);
    EXPECT_EQ(a.laser, b.laser);
    EXPECT_EQ(a.frame, b.frame);
    EXPECT_EQ(a.u, b.u);
    EXPECT_EQ(a.v, b.v);
    EXPECT_EQ(a.confidence, b.confidence);
    EXPECT_EQ(a.rule, b.rule);
  }
}

TEST_F(CloudIoTest, AnotherProgramsCloudGivesPositionsAndNormals) {
  std::ofstream(dir_ / "other.ply") << "ply\nformat ascii 1.0\nelement vertex 2\n"
                                       "property double x\nproperty double y\nproperty double z\n"
                                       "property float nz\nproperty float ny\nproperty float nx\n"
                                       "end_header\n1 2 3 1 0 0\n-4 5.5 6 0 1 0\n";
  const PointCloud cloud = ReadPointCloud(dir_ / "other.ply", /*require_normals=*/true);
  ASSERT_EQ(cloud.points.size(), 2u);
  EXPECT_EQ(cloud.points[1].point_in_world, Eigen::Vector3f(-4, 5.5f, 6));
  EXPECT_EQ(cloud.points[0].normal, Eigen::Vector3f(0, 0, 1));
  EXPECT_EQ(cloud.points[1].normal, Eigen::Vector3f(0, 1, 0));
  EXPECT_EQ(cloud.points[1].frame, 0u);
}

TEST_F(CloudIoTest, ACloudWithoutNormalsOrPointsIsRefusedByName) {
  std::ofstream(dir_ / "bare.ply") << "ply\nformat ascii 1.0\nelement vertex 1\n"
                                      "property float x\nproperty float y\nproperty float z\n"
                                      "end_header\n1 2 3\n";
  EXPECT_EQ(ReadPointCloud(dir_ / "bare.ply").points.size(), 1u);
  try {
    ReadPointCloud(dir_ / "bare.ply", /*require_normals=*/true);
    FAIL() << "no error";
  } catch (const MeshIoError& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir_ / "bare.ply").string() + ": the cloud has no normals (nx, ny, nz)");
  }
  std::ofstream(dir_ / "empty.ply") << "ply\nformat ascii 1.0\nend_header\n";
  EXPECT_THROW(ReadPointCloud(dir_ / "empty.ply"), MeshIoError);
  EXPECT_THROW(ReadPointCloud(dir_ / "missing.ply"), MeshIoError);
}

}  // namespace
}  // namespace mirrorscan

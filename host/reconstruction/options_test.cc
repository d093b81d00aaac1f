#include "host/reconstruction/options.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"

namespace mirrorscan::reconstruction {
namespace {

std::string ValidationError(const ReconstructOptions& options) {
  try {
    options.Validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Options, TheDefaultsAreValidAndABadValueIsNamed) {
  EXPECT_EQ(ValidationError(ReconstructOptions()), "");
  ReconstructOptions options;
  options.stereo_max_mm = -1;
  EXPECT_NE(ValidationError(options).find("stereo_max_mm is -1"), std::string::npos)
      << ValidationError(options);
  options = {};
  options.cylinder.top_mm = 5;  // below the 10 mm bottom
  EXPECT_NE(ValidationError(options).find("cylinder.top_mm"), std::string::npos);
  options = {};
  options.min_confidence = std::nan("");
  EXPECT_NE(ValidationError(options).find("min_confidence"), std::string::npos);
  options = {};
  options.min_ray_plane_angle_deg = 90;
  EXPECT_NE(ValidationError(options).find("min_ray_plane_angle_deg"), std::string::npos);
  // The core may be wider than the cylinder: it is clipped to it.
  options = {};
  options.cylinder.radius_mm = 300;
  EXPECT_EQ(ValidationError(options), "");
  // Reconstruct() refuses them before reading the archive.
  options.threads = -2;
  EXPECT_THROW(Reconstruct(ScanArchive(), Calibration(), options), std::invalid_argument);
}

}  // namespace
}  // namespace mirrorscan::reconstruction

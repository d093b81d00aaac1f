// Loads the real module and with it libcamera, so it runs natively only (never under
// qemu-aarch64, where loading libcamera.so hangs). With no camera attached (CI) the
// manager starts and lists none; on a board the same assertions hold for what is there.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "firmware/hal/libcamera/libcamera_loader.h"

namespace mirrorscan::hal {
namespace {

namespace fs = std::filesystem;

const fs::path kModule(MIRRORSCAN_LIBCAMERA_MODULE);

TEST(LibcameraModule, CameraManagerStartsAndEnumerates) {
  const std::vector<std::string> ids = ListLibcameraCameras(kModule);
  std::cout << "libcamera lists " << ids.size() << " camera(s)";
  for (const std::string& id : ids) std::cout << " \"" << id << "\"";
  std::cout << "\n";
  // Every id is a real, distinct one.
  for (const std::string& id : ids) EXPECT_FALSE(id.empty());
  std::vector<std::string> sorted = ids;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(std::unique(sorted.begin(), sorted.end()), sorted.end());
  // The process keeps one manager: asking again lists the same cameras.
  EXPECT_EQ(ListLibcameraCameras(kModule), ids);
}

TEST(LibcameraModule, DefaultLookupLoadsTheBuiltModule) {
  unsetenv(kModuleDirEnv);
  EXPECT_EQ(ListLibcameraCameras(), ListLibcameraCameras(kModule));
}

TEST(LibcameraModule, MissingCameraIdNamesItAndTheCamerasThatExist) {
  const std::string missing = "/base/soc/i2c0mux/i2c@1/no-such-sensor@10";
  const std::vector<std::string> ids = ListLibcameraCameras(kModule);
  try {
    OpenLibcameraCamera(kModule, missing);
    FAIL() << "opened a camera that does not exist";
  } catch (const HardwareError& e) {  // thrown inside the module, caught out here
    const std::string message = e.what();
    EXPECT_EQ(e.kind(), HardwareError::Kind::kIo);
    EXPECT_NE(message.find("\"" + missing + "\""), std::string::npos) << message;
    EXPECT_NE(message.find("cameras available: "), std::string::npos) << message;
    if (ids.empty()) {
      EXPECT_NE(message.find("cameras available: none"), std::string::npos) << message;
    }
    for (const std::string& id : ids) {
      EXPECT_NE(message.find("\"" + id + "\""), std::string::npos) << message;
    }
  }
}

}  // namespace
}  // namespace mirrorscan::hal

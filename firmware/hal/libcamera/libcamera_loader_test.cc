// The loader's contract without loading libcamera (this binary also runs under qemu, where
// loading libcamera.so hangs): where the module is looked for, and that every way of
// failing to load it is one clear HardwareError.
#include "firmware/hal/libcamera/libcamera_loader.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include "firmware/hal/libcamera/libcamera_module_abi.h"

namespace mirrorscan::hal {
namespace {

namespace fs = std::filesystem;

// Sets (or unsets) MIRRORSCAN_MODULE_DIR for one test and restores it.
class ScopedModuleDir {
 public:
  explicit ScopedModuleDir(const std::optional<std::string>& dir) {
    if (const char* old = getenv(kModuleDirEnv)) old_ = old;
    if (dir) {
      setenv(kModuleDirEnv, dir->c_str(), 1);
    } else {
      unsetenv(kModuleDirEnv);
    }
  }
  ~ScopedModuleDir() {
    if (old_) {
      setenv(kModuleDirEnv, old_->c_str(), 1);
    } else {
      unsetenv(kModuleDirEnv);
    }
  }

 private:
  std::optional<std::string> old_;
};

// The message of the HardwareError `call` throws; fails the test if it throws nothing else.
template <typename F>
std::string ErrorOf(F call) {
  try {
    call();
  } catch (const HardwareError& e) {
    EXPECT_EQ(e.kind(), HardwareError::Kind::kIo) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no HardwareError";
  return "";
}

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("mirrorscan_loader_test_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(LibcameraLoader, TheBuildPutsTheModuleWhereTheLoaderLooks) {
  const fs::path module(MIRRORSCAN_LIBCAMERA_MODULE);
  ASSERT_TRUE(fs::is_regular_file(module)) << module;
  EXPECT_EQ(module.filename(), kLibcameraModuleFile);
  ScopedModuleDir unset(std::nullopt);
  // This test runs from build/bin; the module is in build/lib/mirrorscan.
  EXPECT_TRUE(fs::equivalent(LibcameraModulePath(), module)) << LibcameraModulePath();
}

TEST(LibcameraLoader, EnvironmentVariableOverridesTheDirectory) {
  ScopedModuleDir dir("/opt/mirrorscan/modules");
  EXPECT_EQ(LibcameraModulePath(), fs::path("/opt/mirrorscan/modules") / kLibcameraModuleFile);
}

TEST(LibcameraLoader, MissingModuleNamesThePathAndTheVariable) {
  const fs::path dir = TempDir("missing");
  ScopedModuleDir env(dir.string());
  const std::string message = ErrorOf([] { OpenLibcameraCamera("/base/imx296@1a"); });
  EXPECT_NE(message.find((dir / kLibcameraModuleFile).string()), std::string::npos) << message;
  EXPECT_NE(message.find(kModuleDirEnv), std::string::npos) << message;
  EXPECT_NE(ErrorOf([] { ListLibcameraCameras(); }).find("no such file"), std::string::npos);
  fs::remove_all(dir);
}

TEST(LibcameraLoader, AFileThatIsNoLibraryIsReportedWithDlerror) {
  const fs::path dir = TempDir("garbage");
  {
    std::ofstream text(dir / kLibcameraModuleFile);
    for (int i = 0; i < 100; ++i) text << "not an ELF file, only text long enough for a header\n";
  }
  ScopedModuleDir env(dir.string());
  const std::string message = ErrorOf([] { OpenLibcameraCamera("/base/imx296@1a"); });
  EXPECT_NE(message.find((dir / kLibcameraModuleFile).string()), std::string::npos) << message;
  EXPECT_NE(message.find("cannot load"), std::string::npos) << message;
  // dlerror()'s own words follow.
  EXPECT_NE(message.find("invalid ELF header"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(LibcameraLoader, ALibraryWithoutTheEntryPointIsRefused) {
  const fs::path module(MIRRORSCAN_NO_ENTRY_MODULE);
  const std::string message = ErrorOf([&] { ListLibcameraCameras(module); });
  EXPECT_NE(message.find(module.string()), std::string::npos) << message;
  EXPECT_NE(message.find("not a mirrorscan camera module"), std::string::npos) << message;
  EXPECT_NE(message.find(kLibcameraModuleSymbol), std::string::npos) << message;
}

TEST(LibcameraLoader, WrongAbiVersionIsRefusedBeforeAnyCall) {
  const fs::path module(MIRRORSCAN_WRONG_ABI_MODULE);
  const std::string message = ErrorOf([&] { OpenLibcameraCamera(module, "/base/imx296@1a"); });
  EXPECT_NE(message.find(module.string()), std::string::npos) << message;
  EXPECT_NE(message.find("ABI version " + std::to_string(kLibcameraModuleAbiVersion + 1)),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("needs " + std::to_string(kLibcameraModuleAbiVersion)), std::string::npos)
      << message;
  // Refused every time, not only on the first attempt.
  EXPECT_EQ(ErrorOf([&] { ListLibcameraCameras(module); }), message);
}

}  // namespace
}  // namespace mirrorscan::hal

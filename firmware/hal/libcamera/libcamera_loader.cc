#include "firmware/hal/libcamera/libcamera_loader.h"

#include <dlfcn.h>

#include <cstdlib>
#include <map>
#include <mutex>
#include <system_error>

#include "firmware/hal/libcamera/libcamera_module_abi.h"

namespace mirrorscan::hal {
namespace {

[[noreturn]] void Fail(const std::string& message) {
  throw HardwareError(HardwareError::Kind::kIo, message);
}

// Loads `module_file` once per process and checks its ABI; never unloaded (see header).
const LibcameraModuleApi& LoadModule(const std::filesystem::path& module_file) {
  static std::mutex mutex;
  static std::map<std::string, const LibcameraModuleApi*> loaded;
  std::lock_guard lock(mutex);
  if (auto it = loaded.find(module_file.string()); it != loaded.end()) return *it->second;

  const std::string where = "libcamera module " + module_file.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(module_file, ec)) {
    Fail(where + ": no such file (set " + std::string(kModuleDirEnv) +
         " to the directory holding " + kLibcameraModuleFile + ")");
  }
  // RTLD_NOW: a module with an unresolved symbol fails here, not at its first call.
  void* handle = dlopen(module_file.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) Fail(where + ": cannot load: " + dlerror());
  dlerror();
  void* symbol = dlsym(handle, kLibcameraModuleSymbol);
  if (symbol == nullptr) {
    // Copied before dlclose(), which may reuse dlerror()'s buffer.
    const char* error = dlerror();
    const std::string reason = error ? error : std::string(kLibcameraModuleSymbol) + " is null";
    dlclose(handle);
    Fail(where + ": not a mirrorscan camera module: " + reason);
  }
  using Entry = const LibcameraModuleApi* (*)();
  const LibcameraModuleApi* api = reinterpret_cast<Entry>(symbol)();
  if (api == nullptr || api->abi_version != kLibcameraModuleAbiVersion) {
    const std::string found = api ? std::to_string(api->abi_version) : "none";
    dlclose(handle);
    Fail(where + ": module ABI version " + found + ", this program needs " +
         std::to_string(kLibcameraModuleAbiVersion) + " (rebuild the module with the program)");
  }
  loaded.emplace(module_file.string(), api);
  return *api;
}

}  // namespace

std::filesystem::path LibcameraModulePath() {
  if (const char* dir = std::getenv(kModuleDirEnv); dir != nullptr && *dir != '\0') {
    return std::filesystem::path(dir) / kLibcameraModuleFile;
  }
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) Fail("libcamera module: cannot find the running executable: " + ec.message());
  return exe.parent_path().parent_path() / "lib" / "mirrorscan" / kLibcameraModuleFile;
}

std::unique_ptr<Camera> OpenLibcameraCamera(const std::string& camera_id) {
  return OpenLibcameraCamera(LibcameraModulePath(), camera_id);
}

std::vector<std::string> ListLibcameraCameras() {
  return ListLibcameraCameras(LibcameraModulePath());
}

std::unique_ptr<Camera> OpenLibcameraCamera(const std::filesystem::path& module_file,
                                            const std::string& camera_id) {
  return LoadModule(module_file).open_camera(camera_id);
}

std::vector<std::string> ListLibcameraCameras(const std::filesystem::path& module_file) {
  return LoadModule(module_file).list_cameras();
}

}  // namespace mirrorscan::hal

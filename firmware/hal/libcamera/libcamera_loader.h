#pragma once

// Opens libcamera cameras through the libcamera module, a shared library loaded with
// dlopen only when asked for. Nothing here links libcamera: a process that never calls
// these functions never loads it (under qemu-aarch64 merely loading Debian's libcamera.so
// hangs the process before main, so mirrorscand and the tests must not depend on it).
//
// The module file is libmirrorscan_camera_libcamera.so, looked up in
//   1. $MIRRORSCAN_MODULE_DIR, if that environment variable is set (and not empty);
//   2. otherwise ../lib/mirrorscan beside the running executable (build/bin ->
//      build/lib/mirrorscan, and /usr/bin -> /usr/lib/mirrorscan as the mirrorscand
//      package installs it: a private directory, since a module has no SONAME and does
//      not belong in the linker's path).
// It is loaded once and stays loaded for the life of the process (libcamera's camera
// manager lives as long), so cameras it made stay valid.
//
// Every failure is a HardwareError kIo whose message names what failed: the module path
// and dlerror() when the module is missing or broken, both versions on an ABI mismatch,
// the camera id and the ids available when there is no such camera. There is no fallback.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "firmware/hal/camera.h"

namespace mirrorscan::hal {

inline constexpr char kModuleDirEnv[] = "MIRRORSCAN_MODULE_DIR";
inline constexpr char kLibcameraModuleFile[] = "libmirrorscan_camera_libcamera.so";

// Where the module is looked for (rules above); the file need not exist.
std::filesystem::path LibcameraModulePath();

// Opens the camera `camera_id` (libcamera's id string, e.g. the Pi's
// "/base/axi/pcie@120000/rp1/i2c@88000/imx296@1a"), acquired for this process. Configure()
// then Start() it as any hal::Camera.
std::unique_ptr<Camera> OpenLibcameraCamera(const std::string& camera_id);
// The ids of the cameras libcamera sees (empty if there are none).
std::vector<std::string> ListLibcameraCameras();

// The same from an explicit module file (tests, tools).
std::unique_ptr<Camera> OpenLibcameraCamera(const std::filesystem::path& module_file,
                                            const std::string& camera_id);
std::vector<std::string> ListLibcameraCameras(const std::filesystem::path& module_file);

}  // namespace mirrorscan::hal

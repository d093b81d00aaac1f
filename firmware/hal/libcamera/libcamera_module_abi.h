#pragma once

// The interface between the libcamera module (libmirrorscan_camera_libcamera.so, loaded
// with dlopen) and its loader. Both sides are built from the same tree with the same
// compiler, so C++ types cross it; the version guards against a stale module file lying
// beside a newer executable. Bump kLibcameraModuleAbiVersion whenever this struct, the
// hal::Camera/Frame/FramePool/CameraConfig layout or HardwareError changes.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "firmware/hal/camera.h"

namespace mirrorscan::hal {

inline constexpr uint32_t kLibcameraModuleAbiVersion = 1;
// The one symbol the module exports (extern "C", so dlsym finds it unmangled).
inline constexpr char kLibcameraModuleSymbol[] = "mirrorscan_camera_libcamera_module";

struct LibcameraModuleApi {
  uint32_t abi_version;  // kLibcameraModuleAbiVersion of the module's build
  // The ids of the cameras libcamera sees. Throws HardwareError kIo if the camera manager
  // cannot start.
  std::vector<std::string> (*list_cameras)();
  // Opens (and acquires) the camera with this id. Throws HardwareError kIo naming the id
  // and the ids available when there is no such camera or it is in use.
  std::unique_ptr<Camera> (*open_camera)(const std::string& camera_id);
};

}  // namespace mirrorscan::hal

extern "C" {
// Defined by the module: its table of entry points.
const mirrorscan::hal::LibcameraModuleApi* mirrorscan_camera_libcamera_module();
}

// A camera module built against another ABI version: the loader must refuse it before
// calling anything in it (so its entry points are null).
#include "firmware/hal/libcamera/libcamera_module_abi.h"

extern "C" __attribute__((visibility("default"))) const mirrorscan::hal::LibcameraModuleApi*
mirrorscan_camera_libcamera_module() {
  static const mirrorscan::hal::LibcameraModuleApi api{
      mirrorscan::hal::kLibcameraModuleAbiVersion + 1, nullptr, nullptr};
  return &api;
}

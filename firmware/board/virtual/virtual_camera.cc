#include "firmware/board/virtual/virtual_camera.h"

#include <algorithm>
#include <string>
#include <utility>

namespace mirrorscan::virtual_cabinet {

using hal::HardwareError;

VirtualCamera::VirtualCamera(const Renderer& renderer, VirtualCameraOptions options)
    : renderer_(renderer), options_(std::move(options)) {
  const int n = static_cast<int>(renderer_.scene().cameras.size());
  if (options_.camera < 0 || options_.camera >= n) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "virtual camera: camera " + std::to_string(options_.camera) +
                            " not in the scene (" + std::to_string(n) + " cameras)");
  }
  if (!options_.slide_time) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "virtual camera: no slide time source");
  }
}

VirtualCamera::~VirtualCamera() { Stop(); }

void VirtualCamera::CheckConfig(const hal::CameraConfig& config) {
  const auto& k = renderer_.scene().cameras[static_cast<size_t>(options_.camera)].camera.intrinsics;
  if (config.width != k.width || config.height != k.height) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera.width/height: the virtual camera renders " +
                            std::to_string(k.width) + "x" + std::to_string(k.height));
  }
  if (config.fps <= 0.0) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera.fps: a live camera needs fps > 0");
  }
}

hal::ThreadedCamera::Produced VirtualCamera::Plan(uint64_t sequence) {
  const int n = drop_every_.load();
  if (n > 0 && (sequence + 1) % static_cast<uint64_t>(n) == 0) return Produced::kDrop;
  return Produced::kFrame;
}

hal::ThreadedCamera::Produced VirtualCamera::Produce(uint64_t sequence, int64_t timestamp_ns,
                                                     uint8_t* pixels) {
  // Rendering starts when the camera thread gets to it, which may be later than the
  // frame's exposure time: the frame shows the slide where it was at exposure.
  const double t = options_.slide_time(timestamp_ns);
  const bool lasers = options_.lasers_on ? options_.lasers_on() : true;
  const GrayImage image = renderer_.RenderFrame(options_.camera, t, sequence, lasers);
  std::copy(image.pixels.begin(), image.pixels.end(), pixels);
  return Produced::kFrame;
}

}  // namespace mirrorscan::virtual_cabinet

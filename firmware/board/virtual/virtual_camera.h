#pragma once

#include <atomic>
#include <cstdint>
#include <functional>

#include "boards/virtual/renderer.h"
#include "firmware/hal/camera.h"

namespace mirrorscan::virtual_cabinet {

struct VirtualCameraOptions {
  int camera = 0;  // index into the scene's cameras
  // The slide time in seconds at the frame's exposure (steady clock, ns); the firmware's
  // simulated drive (or a test) drives it. Required.
  std::function<double(int64_t exposure_ns)> slide_time;
  // Whether the lasers are on at the moment of exposure. Empty = always on.
  std::function<bool()> lasers_on;
};

// A Camera whose frames the virtual cabinet renders: at the configured fps, frame
// `sequence` is Renderer::RenderFrame(camera, slide_time(its timestamp), sequence,
// lasers_on()).
// slide_time() and lasers_on() are each called exactly once per rendered frame, on the
// camera's thread, in sequence order, and never for a stalled or dropped frame.
//
// Configure() must ask for the scene camera's size and a live rate (fps > 0); anything
// else is HardwareError kInvalidArgument. Rendering is slower than a sensor: when a frame
// takes longer than the period, the next starts late rather than being dropped. The
// camera's clock (clock_ns, ThreadedCamera) stands still while it renders, so a stall
// watchdog judges it on its own time: a busy host makes its frames late, never "stalled";
// SetStalled(true) lets its clock run with no frames, which a watchdog sees at once.
//
// Fault injection (any thread, any time):
//  - SetStalled(true) (ThreadedCamera): the camera stops delivering; no frame, no
//    sequence number, no drop is counted (a hung sensor: only a watchdog notices).
//  - SetDropEveryNth(n): frames with (sequence + 1) % n == 0 are lost as if no buffer
//    were free: they leave a sequence gap and count in dropped(). 0 turns it off.
//
// The renderer must outlive the camera.
class VirtualCamera final : public hal::ThreadedCamera {
 public:
  VirtualCamera(const Renderer& renderer, VirtualCameraOptions options);
  ~VirtualCamera() override;

  void SetDropEveryNth(int n) { drop_every_ = n > 0 ? n : 0; }

 protected:
  void CheckConfig(const hal::CameraConfig& config) override;
  Produced Plan(uint64_t sequence) override;
  Produced Produce(uint64_t sequence, int64_t timestamp_ns, uint8_t* pixels) override;

 private:
  const Renderer& renderer_;
  VirtualCameraOptions options_;
  std::atomic<int> drop_every_{0};
};

}  // namespace mirrorscan::virtual_cabinet

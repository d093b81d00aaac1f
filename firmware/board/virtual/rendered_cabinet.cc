#include "firmware/board/virtual/rendered_cabinet.h"

#include <string>
#include <utility>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "firmware/board/virtual/virtual_camera.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::board {
namespace {

class RenderedCabinet final : public VirtualCabinet {
 public:
  RenderedCabinet(virtual_cabinet::Scene scene, double sweep_start_mm)
      : scene_(std::move(scene)), renderer_(scene_), sweep_start_mm_(sweep_start_mm) {}

  std::unique_ptr<hal::Camera> MakeCamera(int scene_camera, std::function<double(int64_t)> slide_mm,
                                          std::function<bool()> lasers_on) override {
    if (scene_camera < 0 || scene_camera >= static_cast<int>(scene_.cameras.size())) {
      throw hal::HardwareError(hal::HardwareError::Kind::kInvalidArgument,
                               "virtual camera id " + std::to_string(scene_camera) +
                                   ": the scene has " + std::to_string(scene_.cameras.size()) +
                                   " cameras");
    }
    // The per-camera precomputation takes seconds: do it now, not at the first frame of
    // a scan.
    renderer_.RenderFrame(scene_camera, 0.0, 0, false);
    virtual_cabinet::VirtualCameraOptions options;
    options.camera = scene_camera;
    const double start_mm = sweep_start_mm_;
    const double speed = scene_.lasers.speed_mm_s;
    // Laser k is at start + speed·t + k·spacing: the slide's travel since the sweep start
    // is speed·t.
    options.slide_time = [slide_mm = std::move(slide_mm), start_mm, speed](int64_t exposure_ns) {
      return (slide_mm(exposure_ns) - start_mm) / speed;
    };
    options.lasers_on = std::move(lasers_on);
    return std::make_unique<virtual_cabinet::VirtualCamera>(renderer_, std::move(options));
  }

 private:
  virtual_cabinet::Scene scene_;
  virtual_cabinet::Renderer renderer_;
  double sweep_start_mm_;
};

}  // namespace

std::unique_ptr<VirtualCabinet> OpenRenderedCabinet(const std::filesystem::path& scene,
                                                    double sweep_start_mm) {
  return std::make_unique<RenderedCabinet>(virtual_cabinet::Scene::Load(scene), sweep_start_mm);
}

}  // namespace mirrorscan::board

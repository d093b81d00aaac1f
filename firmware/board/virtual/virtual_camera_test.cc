#include "firmware/board/virtual/virtual_camera.h"

#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <mutex>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "firmware/hal/camera_test_util.h"

namespace mirrorscan::virtual_cabinet {
namespace {

using hal::CameraConfig;
using hal::Frame;
using hal::HardwareError;
using hal::testing::FrameQueue;
using hal::testing::WaitFor;
using std::chrono::milliseconds;

constexpr int kWidth = 128, kHeight = 96;

// The cylinder scene seen by one small upper camera, so a frame renders in milliseconds.
const Renderer& SmallRenderer() {
  static const std::unique_ptr<Renderer> renderer = [] {
    const std::string dir = std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes";
    nlohmann::json json = {
        {"subject",
         {{"type", "cylinder"}, {"radius_mm", 150}, {"height_mm", 1000}, {"bottom_mm", 400}}},
        {"cameras",
         {{{"name", "upper"},
           {"position_mm", {0, -1800, 2150}},
           {"look_at_mm", {0, 300, 1350}},
           {"width", kWidth},
           {"height", kHeight},
           {"f_px", 1400.0 * kWidth / 1024}}}},
        {"seed", 3}};
    return std::make_unique<Renderer>(Scene::Parse(json, "test", dir));
  }();
  return *renderer;
}

CameraConfig Config(double fps, int buffers = 16) {
  CameraConfig c;
  c.width = kWidth;
  c.height = kHeight;
  c.fps = fps;
  c.exposure_us = 1000;
  c.buffer_count = buffers;
  return c;
}

// A slide that advances 0.5 s per rendered frame from t = 4 s, lasers on every other
// frame; remembers what it answered, in order.
struct ScriptedSources {
  std::mutex mutex;
  std::vector<double> times;
  std::vector<int64_t> asked_at_ns;  // the exposure times slide_time was asked for
  std::vector<bool> lasers;
  VirtualCameraOptions Options() {
    VirtualCameraOptions o;
    o.slide_time = [this](int64_t exposure_ns) {
      std::lock_guard lock(mutex);
      asked_at_ns.push_back(exposure_ns);
      times.push_back(4.0 + 0.5 * static_cast<double>(times.size()));
      return times.back();
    };
    o.lasers_on = [this] {
      std::lock_guard lock(mutex);
      lasers.push_back(lasers.size() % 2 == 0);
      return static_cast<bool>(lasers.back());
    };
    return o;
  }
};

bool SamePixels(const Frame& f, const GrayImage& image) {
  const auto v = f.view();
  return v.width == image.width && v.height == image.height && v.stride == image.width &&
         std::memcmp(v.data, image.pixels.data(), image.pixels.size()) == 0;
}

TEST(VirtualCamera, FramesAreTheRendererFramesForTheSlideTimeOfTheirExposure) {
  const Renderer& renderer = SmallRenderer();
  ScriptedSources sources;
  VirtualCamera cam(renderer, sources.Options());
  cam.Configure(Config(60));
  FrameQueue q;
  cam.Start(q.OnFrame());
  std::vector<Frame> frames;
  for (int i = 0; i < 6; ++i) {
    frames.push_back(q.Pop());
    ASSERT_TRUE(frames.back().valid()) << i;
  }
  cam.Stop();
  ASSERT_GE(sources.times.size(), frames.size());
  bool lasers_visible = false;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& f = frames[i];
    EXPECT_EQ(f.sequence(), i);
    // The slide is asked where it was when this frame was exposed, not when it is rendered.
    EXPECT_EQ(sources.asked_at_ns[i], f.timestamp_ns());
    if (i > 0) {
      EXPECT_GT(f.timestamp_ns(), frames[i - 1].timestamp_ns());
    }
    const GrayImage expected =
        renderer.RenderFrame(0, sources.times[i], f.sequence(), sources.lasers[i]);
    EXPECT_TRUE(SamePixels(f, expected)) << "frame " << i << " t " << sources.times[i];
    if (sources.lasers[i]) {
      lasers_visible |= !SamePixels(f, renderer.RenderFrame(0, sources.times[i], i, false));
    }
  }
  EXPECT_TRUE(lasers_visible) << "the test would not notice the laser switch";
}

TEST(VirtualCamera, StallStopsDeliveringAndResumes) {
  ScriptedSources sources;
  VirtualCamera cam(SmallRenderer(), sources.Options());
  cam.Configure(Config(100));
  FrameQueue q;
  cam.Start(q.OnFrame());
  Frame first = q.Pop();
  ASSERT_TRUE(first.valid());
  cam.SetStalled(true);
  // Frames queued or in flight still arrive; then silence for many periods.
  uint64_t before = first.sequence();
  for (Frame f = q.Pop(milliseconds(50)); f.valid(); f = q.Pop(milliseconds(50))) {
    before = f.sequence();
  }
  EXPECT_FALSE(q.Pop(milliseconds(100)).valid());  // 10 periods at 100 fps
  EXPECT_EQ(cam.dropped(), 0u);
  cam.SetStalled(false);
  Frame next = q.Pop();
  ASSERT_TRUE(next.valid());
  EXPECT_EQ(next.sequence(), before + 1);  // a stall leaves no sequence gap
  cam.Stop();
}

TEST(VirtualCamera, DropEveryNthLeavesGapsAndCountsThem) {
  ScriptedSources sources;
  VirtualCamera cam(SmallRenderer(), sources.Options());
  cam.SetDropEveryNth(3);
  cam.Configure(Config(100));
  FrameQueue q;
  cam.Start(q.OnFrame());
  std::vector<uint64_t> sequences;
  std::vector<Frame> held;  // fewer than the 16 buffers: no drop for want of one
  for (int i = 0; i < 8; ++i) {
    held.push_back(q.Pop());
    ASSERT_TRUE(held.back().valid());
    sequences.push_back(held.back().sequence());
  }
  cam.Stop();
  EXPECT_EQ(sequences, (std::vector<uint64_t>{0, 1, 3, 4, 6, 7, 9, 10}));
  EXPECT_GE(cam.dropped(), 3u);
  // Dropped frames are never rendered: one slide time per delivered frame.
  EXPECT_EQ(sources.times.size(), held.size() + q.size());
}

TEST(VirtualCamera, RejectsSettingsItCannotRender) {
  ScriptedSources sources;
  VirtualCamera cam(SmallRenderer(), sources.Options());
  CameraConfig c = Config(30);
  c.width = 1024;
  EXPECT_THROW(cam.Configure(c), HardwareError);
  EXPECT_THROW(cam.Configure(Config(0)), HardwareError);
  VirtualCameraOptions no_time;
  EXPECT_THROW(VirtualCamera(SmallRenderer(), no_time), HardwareError);
  VirtualCameraOptions bad_camera = sources.Options();
  bad_camera.camera = 1;
  EXPECT_THROW(VirtualCamera(SmallRenderer(), bad_camera), HardwareError);
}

}  // namespace
}  // namespace mirrorscan::virtual_cabinet

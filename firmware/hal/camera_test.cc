#include "firmware/hal/camera.h"

#include <chrono>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "firmware/hal/camera_test_util.h"

namespace mirrorscan::hal {
namespace {

using std::chrono::milliseconds;
using testing::FrameQueue;
using testing::WaitFor;

// Fills every pixel with the low byte of the sequence number.
class CountingCamera final : public ThreadedCamera {
 public:
  ~CountingCamera() override { Stop(); }
  std::atomic<uint64_t> produced{0};

 protected:
  Produced Produce(uint64_t sequence, int64_t, uint8_t* pixels) override {
    std::fill_n(pixels, config().width * config().height, static_cast<uint8_t>(sequence));
    ++produced;
    return Produced::kFrame;
  }
};

// Takes `work` of host time per frame, as the virtual cabinet's renderer does.
class BusyCamera final : public ThreadedCamera {
 public:
  explicit BusyCamera(milliseconds work) : work_(work) {}
  ~BusyCamera() override { Stop(); }

 protected:
  Produced Produce(uint64_t, int64_t, uint8_t*) override {
    std::this_thread::sleep_for(work_);
    return Produced::kFrame;
  }

 private:
  const milliseconds work_;
};

CameraConfig SmallConfig(double fps) {
  CameraConfig c;
  c.width = 32;
  c.height = 16;
  c.fps = fps;
  c.exposure_us = 1000;
  c.buffer_count = 3;
  return c;
}

void ExpectInvalid(const CameraConfig& c, const std::string& key) {
  try {
    c.Validate();
    ADD_FAILURE() << "accepted bad " << key;
  } catch (const HardwareError& e) {
    EXPECT_EQ(e.kind(), HardwareError::Kind::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("camera." + key), std::string::npos) << e.what();
  }
}

TEST(CameraConfig, ValidatesEveryField) {
  EXPECT_NO_THROW(CameraConfig().Validate());
  CameraConfig c;
  c.width = 8;
  ExpectInvalid(c, "width");
  c = {}, c.height = 0, ExpectInvalid(c, "height");
  c = {}, c.fps = -1, ExpectInvalid(c, "fps");
  c = {}, c.exposure_us = 0, ExpectInvalid(c, "exposure_us");
  c = {}, c.exposure_us = 40000, ExpectInvalid(c, "exposure_us");  // > 33 ms at 30 fps
  c = {}, c.gain = 0.5, ExpectInvalid(c, "gain");
  c = {}, c.buffer_count = 1, ExpectInvalid(c, "buffer_count");
}

TEST(ThreadedCamera, StateErrors) {
  CountingCamera cam;
  FrameQueue q;
  EXPECT_THROW(cam.Start(q.OnFrame()), HardwareError);  // not configured
  cam.Configure(SmallConfig(100));
  cam.Start(q.OnFrame());
  EXPECT_THROW(cam.Start(q.OnFrame()), HardwareError);
  EXPECT_THROW(cam.Configure(SmallConfig(100)), HardwareError);
  cam.Stop();
  cam.Stop();  // idempotent
  EXPECT_FALSE(cam.streaming());
}

TEST(ThreadedCamera, PoolExhaustionDropsAndNeverBlocksTheProducer) {
  CountingCamera cam;
  cam.Configure(SmallConfig(500));
  FrameQueue q;
  cam.Start(q.OnFrame());
  // Hold every frame: after the pool's three buffers the camera must keep running and
  // count each further frame as dropped.
  ASSERT_TRUE(WaitFor([&] { return cam.dropped() >= 10; }));
  EXPECT_EQ(q.size(), 3u);
  EXPECT_EQ(cam.produced.load(), 3u);
  // Releasing buffers lets frames through again, with a sequence gap for the lost ones.
  for (int i = 0; i < 3; ++i) {
    Frame f = q.Pop();
    ASSERT_TRUE(f.valid());
    EXPECT_EQ(f.sequence(), static_cast<uint64_t>(i));
    EXPECT_EQ(f.view().data[0], static_cast<uint8_t>(i));
  }
  Frame after = q.Pop();
  ASSERT_TRUE(after.valid());
  EXPECT_GT(after.sequence(), 3u);
  cam.Stop();
}

TEST(ThreadedCamera, FramesOutliveTheCamera) {
  Frame kept;
  {
    CountingCamera cam;
    cam.Configure(SmallConfig(0));
    FrameQueue q;
    cam.Start(q.OnFrame());
    kept = q.Pop();
    cam.Stop();
  }
  ASSERT_TRUE(kept.valid());
  EXPECT_EQ(kept.view().width, 32);
  EXPECT_EQ(kept.view().stride, 32);
  EXPECT_EQ(kept.view().data[32 * 16 - 1], 0);
  kept.Release();
  EXPECT_FALSE(kept.valid());
}

TEST(ThreadedCamera, StopIsPromptWhileWaitingForAPeriodOrABuffer) {
  for (double fps : {0.5, 0.0}) {  // a 2 s period; or all buffers held with fps 0
    CountingCamera cam;
    cam.Configure(SmallConfig(fps));
    FrameQueue q;
    cam.Start(q.OnFrame());
    if (fps > 0.0) {
      ASSERT_TRUE(q.Pop().valid());  // the first frame comes at once
    } else {
      ASSERT_TRUE(WaitFor([&] { return q.size() == 3; }));  // the pool is empty
    }
    const auto t0 = std::chrono::steady_clock::now();
    cam.Stop();
    EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds(500)) << "fps " << fps;
    EXPECT_EQ(cam.dropped(), 0u);
  }
}

// A stall watchdog reads Camera::clock_ns(): a frame that takes the host 150 ms to make
// is late, not a stalled sensor, so the camera's clock stands still meanwhile; a sensor
// that makes no frames lets it run with the steady clock.
TEST(ThreadedCamera, ItsClockStandsStillWhileTheHostMakesAFrameAndRunsWhileItMakesNone) {
  BusyCamera cam(milliseconds(150));
  cam.Configure(SmallConfig(50));  // a 20 ms period: every frame is late
  FrameQueue q;
  cam.Start(q.OnFrame());
  ASSERT_TRUE(q.Pop().valid());
  const int64_t clock0 = cam.clock_ns(), steady0 = SteadyNowNs();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(q.Pop().valid());
  const int64_t clock1 = cam.clock_ns(), steady1 = SteadyNowNs();
  std::printf("3 frames of 150 ms work: steady %.1f ms, camera clock %.1f ms\n",
              (steady1 - steady0) * 1e-6, (clock1 - clock0) * 1e-6);
  EXPECT_GE(steady1 - steady0, 300'000'000);
  // It waits for no period (each is over when a frame is done): the clock may only run
  // up to a scheduled exposure, at most one period per frame.
  EXPECT_LE(clock1 - clock0, 3 * 20'000'000);

  cam.SetStalled(true);                            // a hung sensor
  std::this_thread::sleep_for(milliseconds(200));  // a frame in the making is done by now
  while (q.Pop(milliseconds(0)).valid()) {
  }
  const int64_t clock2 = cam.clock_ns(), steady2 = SteadyNowNs();
  std::this_thread::sleep_for(milliseconds(300));
  const int64_t clock3 = cam.clock_ns(), steady3 = SteadyNowNs();
  std::printf("stalled: steady %.1f ms, camera clock %.1f ms\n", (steady3 - steady2) * 1e-6,
              (clock3 - clock2) * 1e-6);
  // It keeps up with the steady clock, short at most by how late its thread wakes for the
  // period at hand (it catches up on every wake-up that makes no frame).
  EXPECT_LE(clock3 - clock2, steady3 - steady2 + 20'000'000);
  EXPECT_GE(clock3 - clock2, steady3 - steady2 - 40'000'000);
  cam.Stop();
}

}  // namespace
}  // namespace mirrorscan::hal

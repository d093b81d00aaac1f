#include "firmware/hal/replay/replay_camera.h"

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/hal/camera_test_util.h"

namespace mirrorscan::hal {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using testing::FrameQueue;
using testing::WaitFor;

constexpr int kWidth = 24, kHeight = 16;

// A fresh directory per test; frame i has every pixel = 10 * i + 1 except pixel (2, 1) = 3,
// so content, order and layout are all checkable.
class ReplayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("replay_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::vector<uint8_t> Pixels(int i) {
    std::vector<uint8_t> p(kWidth * kHeight, static_cast<uint8_t>(10 * i + 1));
    p[kWidth + 2] = 3;  // (u, v) = (2, 1)
    return p;
  }
  void WriteFrames(int n) {
    // Written out of order: playback follows the names, not creation.
    for (int i = n - 1; i >= 0; --i) {
      char name[32];
      std::snprintf(name, sizeof(name), "frame_%04d.pgm", i);
      WritePgm(dir_ / name, kWidth, kHeight, Pixels(i).data());
    }
  }
  static CameraConfig Config(double fps, int buffers = 4) {
    CameraConfig c;
    c.width = kWidth;
    c.height = kHeight;
    c.fps = fps;
    c.exposure_us = 1000;
    c.buffer_count = buffers;
    return c;
  }
  // Start() must fail with `kind` and a message naming `name`.
  void ExpectStartFails(ReplayCamera& cam, HardwareError::Kind kind, const std::string& name,
                        const std::string& problem = "") {
    FrameQueue q;
    try {
      cam.Start(q.OnFrame());
      ADD_FAILURE() << "Start() accepted " << name;
    } catch (const HardwareError& e) {
      EXPECT_EQ(e.kind(), kind) << e.what();
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(problem), std::string::npos) << e.what();
    }
    EXPECT_FALSE(cam.streaming());
  }

  fs::path dir_;
};

TEST_F(ReplayTest, PlaysFilesInNameOrderWithIncreasingSequenceAndTimestamps) {
  WriteFrames(5);
  fs::path junk = dir_ / "notes.txt";
  std::ofstream(junk) << "not a frame";
  ReplayCamera cam({dir_, false});
  cam.Configure(Config(200));
  FrameQueue q;
  cam.Start(q.OnFrame(), q.OnEnd());
  ASSERT_EQ(cam.files().size(), 5u);
  int64_t last_ts = 0;
  for (int i = 0; i < 5; ++i) {
    Frame f = q.Pop();
    ASSERT_TRUE(f.valid()) << i;
    EXPECT_EQ(f.sequence(), static_cast<uint64_t>(i));
    EXPECT_EQ(f.view().width, kWidth);
    EXPECT_EQ(f.view().height, kHeight);
    EXPECT_EQ(f.view().data[0], 10 * i + 1);
    EXPECT_EQ(f.view().data[kWidth + 2], 3);
    EXPECT_EQ(f.exposure_us(), 1000);
    if (i > 0) {
      EXPECT_GT(f.timestamp_ns(), last_ts);
      EXPECT_GE(f.timestamp_ns() - last_ts, 5'000'000 - 1000);  // one period at 200 fps
    }
    last_ts = f.timestamp_ns();
    EXPECT_LE(last_ts, SteadyNowNs());
  }
  ASSERT_TRUE(q.WaitEnd());
  EXPECT_FALSE(q.error().has_value());
  EXPECT_EQ(cam.dropped(), 0u);
  cam.Stop();
}

TEST_F(ReplayTest, LoopsAndPlaysAsFastAsConsumed) {
  WriteFrames(3);
  ReplayCamera cam({dir_, true});
  cam.Configure(Config(0, 2));
  FrameQueue q;
  cam.Start(q.OnFrame(), q.OnEnd());
  // A slow consumer with fps 0 loses nothing: the camera waits for buffers.
  for (int i = 0; i < 8; ++i) {
    Frame f = q.Pop();
    ASSERT_TRUE(f.valid()) << i;
    EXPECT_EQ(f.sequence(), static_cast<uint64_t>(i));
    EXPECT_EQ(f.view().data[0], 10 * (i % 3) + 1);
    if (i == 2) std::this_thread::sleep_for(milliseconds(20));
  }
  EXPECT_EQ(cam.dropped(), 0u);
  cam.Stop();
}

TEST_F(ReplayTest, PoolExhaustionCountsDropsAndNeverBlocksTheProducer) {
  WriteFrames(4);
  ReplayCamera cam({dir_, true});
  cam.Configure(Config(500, 2));
  FrameQueue q;
  cam.Start(q.OnFrame(), q.OnEnd());
  ASSERT_TRUE(WaitFor([&] { return cam.dropped() >= 6; }));
  EXPECT_EQ(q.size(), 2u);  // the consumer holds the whole pool
  Frame a = q.Pop(), b = q.Pop();
  EXPECT_EQ(a.sequence(), 0u);
  EXPECT_EQ(b.sequence(), 1u);
  a.Release();
  b.Release();
  // The producer kept counting frames meanwhile: the next one shows the gap, and its
  // pixels are the file its sequence number stands for.
  Frame c = q.Pop();
  ASSERT_TRUE(c.valid());
  EXPECT_GE(c.sequence(), 8u);
  EXPECT_EQ(c.view().data[0], 10 * (c.sequence() % 4) + 1);
  cam.Stop();
}

TEST_F(ReplayTest, StopIsPrompt) {
  WriteFrames(2);
  ReplayCamera cam({dir_, true});
  cam.Configure(Config(1));  // a 1 s period
  FrameQueue q;
  cam.Start(q.OnFrame());
  ASSERT_TRUE(q.Pop().valid());
  const auto t0 = std::chrono::steady_clock::now();
  cam.Stop();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, milliseconds(300));
  EXPECT_FALSE(cam.streaming());
  // And it starts again from sequence 0.
  cam.Start(q.OnFrame());
  Frame f = q.Pop();
  ASSERT_TRUE(f.valid());
  EXPECT_EQ(f.sequence(), 0u);
  cam.Stop();
}

TEST_F(ReplayTest, BadOrMissingFilesNameTheFile) {
  {
    ReplayCamera cam({dir_ / "missing", false});
    cam.Configure(Config(30));
    ExpectStartFails(cam, HardwareError::Kind::kIo, "missing");
  }
  {
    ReplayCamera cam({dir_, false});  // empty directory
    cam.Configure(Config(30));
    ExpectStartFails(cam, HardwareError::Kind::kIo, dir_.string());
  }
  WriteFrames(2);
  {
    ReplayCamera cam({dir_, false});  // wrong size
    CameraConfig c = Config(30);
    c.width = kWidth * 2;
    cam.Configure(c);
    ExpectStartFails(cam, HardwareError::Kind::kInvalidArgument, "frame_0000.pgm");
  }
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"P2\n24 16\n255\n", "magic"},     // ASCII PGM
      {"P5\n24 16\n65535\n", "maxval"},  // 16-bit
      {"P5\n24 x\n255\n", "height"},     // garbage
      {"P5\n# comment\n24 16\n255\n012", "truncated"},
  };
  for (const auto& [content, problem] : bad) {
    std::ofstream(dir_ / "frame_0001.pgm", std::ios::binary | std::ios::trunc) << content;
    ReplayCamera cam({dir_, false});
    cam.Configure(Config(30));
    ExpectStartFails(cam, HardwareError::Kind::kIo, "frame_0001.pgm", problem);
  }
}

TEST_F(ReplayTest, AFileThatGoesBadWhileStreamingEndsTheStreamNamingIt) {
  WriteFrames(3);
  ReplayCamera cam({dir_, false});
  cam.Configure(Config(0, 2));
  FrameQueue q;
  cam.Start(q.OnFrame(), q.OnEnd());
  // fps 0 with two buffers: the camera waits for one while the consumer holds 0 and 1.
  ASSERT_TRUE(WaitFor([&] { return q.size() == 2; }));
  fs::remove(dir_ / "frame_0002.pgm");
  { Frame a = q.Pop(), b = q.Pop(); }
  ASSERT_TRUE(q.WaitEnd());
  ASSERT_TRUE(q.error().has_value());
  EXPECT_NE(q.error()->find("frame_0002.pgm"), std::string::npos) << *q.error();
  cam.Stop();
}

TEST(Pgm, HeaderWithCommentsRoundTrips) {
  const fs::path file = fs::temp_directory_path() / ("pgm_" + std::to_string(::getpid()) + ".pgm");
  std::ofstream(file, std::ios::binary) << "P5 # c\n# another\n3 2 # w h\n200\n"
                                        << "abcdef";
  const PgmHeader h = ReadPgmHeader(file);
  EXPECT_EQ(h.width, 3);
  EXPECT_EQ(h.height, 2);
  EXPECT_EQ(h.maxval, 200);
  uint8_t px[6];
  ReadPgmPixels(file, h, px);
  EXPECT_EQ(px[0], 'a');
  EXPECT_EQ(px[5], 'f');
  fs::remove(file);
}

}  // namespace
}  // namespace mirrorscan::hal

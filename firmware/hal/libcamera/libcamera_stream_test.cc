#include "firmware/hal/libcamera/libcamera_stream.h"

#include <gtest/gtest.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

namespace mirrorscan::hal::libcamera_stream {
namespace {

TEST(ChooseFormat, PrefersGreyThenYuv420ThenRawBayer) {
  const uint32_t rgb888 = Fourcc('R', 'G', '2', '4');
  const uint32_t nv12 = Fourcc('N', 'V', '1', '2');
  const uint32_t srggb10 = Fourcc('R', 'G', '1', '0');

  auto chosen = ChooseFormat({rgb888, kFourccSbggr8, kFourccYuv420, kFourccR8, nv12});
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(chosen->fourcc, kFourccR8);
  EXPECT_EQ(chosen->layout, PixelLayout::kGrey);

  chosen = ChooseFormat({rgb888, kFourccSbggr8, kFourccYuv420, nv12});
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(chosen->fourcc, kFourccYuv420);
  EXPECT_EQ(chosen->layout, PixelLayout::kYuv420);

  chosen = ChooseFormat({srggb10, kFourccSgbrg8, rgb888});
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(chosen->fourcc, kFourccSgbrg8);
  EXPECT_EQ(chosen->layout, PixelLayout::kBayer8);

  EXPECT_FALSE(ChooseFormat({rgb888, nv12, srggb10}).has_value());
  EXPECT_FALSE(ChooseFormat({}).has_value());
}

TEST(ChooseFormat, FourccsMatchLibcamerasCodes) {
  // The DRM codes libcamera's formats.h gives (little-endian fourcc).
  EXPECT_EQ(kFourccR8, 0x20203852U);
  EXPECT_EQ(kFourccYuv420, 0x32315559U);
  EXPECT_EQ(kFourccSbggr8, 0x31384142U);
}

TEST(SensorControlsFor, FixesExposureGainAndFrameDuration) {
  CameraConfig config;
  config.fps = 30.0;
  config.exposure_us = 4000;
  config.gain = 2.5;
  const SensorControls controls = SensorControlsFor(config);
  EXPECT_FALSE(controls.ae_enable);
  EXPECT_EQ(controls.exposure_us, 4000);
  EXPECT_FLOAT_EQ(controls.analogue_gain, 2.5F);
  EXPECT_EQ(controls.frame_duration_us, 33333);

  config.fps = 60.0;
  config.exposure_us = 16666;  // exactly the period, rounded down: still allowed
  EXPECT_EQ(SensorControlsFor(config).frame_duration_us, 16667);
  EXPECT_LE(SensorControlsFor(config).exposure_us, SensorControlsFor(config).frame_duration_us);
}

TEST(SensorControlsFor, RejectsUnpacedAndInvalidSettings) {
  CameraConfig config;
  config.fps = 0.0;
  try {
    SensorControlsFor(config);
    FAIL() << "fps 0 accepted";
  } catch (const HardwareError& e) {
    EXPECT_EQ(e.kind(), HardwareError::Kind::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("camera.fps"), std::string::npos) << e.what();
  }
  config.fps = 30.0;
  config.exposure_us = 40000;  // longer than the 33 ms frame
  try {
    SensorControlsFor(config);
    FAIL() << "exposure longer than a frame accepted";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("camera.exposure_us"), std::string::npos) << e.what();
  }
}

// A buffer as the ISP writes it: rows padded to `stride`, then (YUV420) the chroma planes.
std::vector<uint8_t> PaddedFrame(int width, int height, size_t stride, size_t trailing) {
  std::vector<uint8_t> plane(stride * static_cast<size_t>(height) + trailing, 0xEE);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      plane[static_cast<size_t>(y) * stride + static_cast<size_t>(x)] =
          static_cast<uint8_t>((x * 7 + y * 13) & 0xFF);
    }
  }
  return plane;
}

TEST(PackPlane, DropsRowPaddingAndKeepsOnlyTheLumaPlane) {
  const int width = 1014, height = 33;
  const size_t stride = 1024;
  // YUV420: a quarter-size U and V plane follow the Y plane, filled with 0xEE.
  const size_t chroma = 2 * (stride / 2) * (height + 1) / 2;
  const std::vector<uint8_t> buffer = PaddedFrame(width, height, stride, chroma);
  std::vector<uint8_t> packed(static_cast<size_t>(width) * height, 0);
  PackPlane(buffer, stride, width, height, packed.data());
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      ASSERT_EQ(packed[static_cast<size_t>(y) * width + static_cast<size_t>(x)],
                static_cast<uint8_t>((x * 7 + y * 13) & 0xFF))
          << "at " << x << "," << y;
    }
  }
}

TEST(PackPlane, UnpaddedPlaneIsCopiedAsIs) {
  const int width = 64, height = 16;
  const std::vector<uint8_t> plane = PaddedFrame(width, height, width, 0);
  std::vector<uint8_t> packed(plane.size(), 0);
  PackPlane(plane, width, width, height, packed.data());
  EXPECT_EQ(packed, plane);
}

TEST(PackPlane, ShortPlaneOrStrideIsAnError) {
  const int width = 64, height = 16;
  std::vector<uint8_t> packed(static_cast<size_t>(width) * height);
  // The last row needs only `width` bytes, not a whole stride: this is just enough.
  std::vector<uint8_t> plane(80 * 15 + 64);
  EXPECT_NO_THROW(PackPlane(plane, 80, width, height, packed.data()));
  plane.pop_back();
  EXPECT_THROW(PackPlane(plane, 80, width, height, packed.data()), HardwareError);
  try {
    PackPlane(std::vector<uint8_t>(4096), 32, width, height, packed.data());
    FAIL() << "stride shorter than a row accepted";
  } catch (const HardwareError& e) {
    EXPECT_EQ(e.kind(), HardwareError::Kind::kIo);
    EXPECT_NE(std::string(e.what()).find("stride 32"), std::string::npos) << e.what();
  }
}

TEST(SequenceCounter, CountsFromZeroAndTurnsGapsIntoMisses) {
  SequenceCounter counter;
  // The sensor had been running: its counter starts anywhere.
  const std::vector<uint32_t> sensor = {1000, 1001, 1002, 1005, 1006, 1010};
  const std::vector<uint64_t> expected_sequence = {0, 1, 2, 5, 6, 10};
  const std::vector<uint64_t> expected_missed = {0, 0, 0, 2, 0, 3};
  uint64_t missed = 0;
  for (size_t i = 0; i < sensor.size(); ++i) {
    const SequenceCounter::Step step = counter.Next(sensor[i]);
    EXPECT_EQ(step.sequence, expected_sequence[i]) << i;
    EXPECT_EQ(step.missed, expected_missed[i]) << i;
    missed += step.missed;
  }
  // Delivered + missed = every frame the sensor made.
  EXPECT_EQ(missed + sensor.size(), sensor.back() - sensor.front() + 1);
}

TEST(SequenceCounter, SurvivesTheCounterWrapping) {
  SequenceCounter counter;
  EXPECT_EQ(counter.Next(0xFFFFFFFEU).sequence, 0U);
  EXPECT_EQ(counter.Next(0xFFFFFFFFU).sequence, 1U);
  const SequenceCounter::Step step = counter.Next(1);  // 0 was lost
  EXPECT_EQ(step.sequence, 3U);
  EXPECT_EQ(step.missed, 1U);
}

TEST(SequenceCounter, RepeatedOrBackwardSequenceIsAnError) {
  SequenceCounter counter;
  counter.Next(50);
  EXPECT_THROW(counter.Next(50), HardwareError);
  EXPECT_THROW(counter.Next(49), HardwareError);
  // The counter is unharmed by the rejected steps.
  EXPECT_EQ(counter.Next(51).sequence, 1U);
}

// A sensor frame whose every pixel is `value`, rows padded to `stride`.
struct PaddedSensorFrame {
  std::vector<uint8_t> pixels;
  SensorFrame frame;
  PaddedSensorFrame(uint32_t sensor_sequence, int width, int height, size_t stride, uint8_t value)
      : pixels(stride * static_cast<size_t>(height), 0xEE) {
    for (int y = 0; y < height; ++y) {
      std::fill_n(pixels.begin() + static_cast<ptrdiff_t>(static_cast<size_t>(y) * stride), width,
                  value);
    }
    frame.sensor_sequence = sensor_sequence;
    frame.plane = pixels;
    frame.stride = stride;
    frame.timestamp_ns = 1'000'000'000LL + sensor_sequence * 33'333'333LL;
    frame.exposure_us = 5000;
    frame.gain = 2.0;
  }
};

bool AllPixelsAre(const Frame& frame, uint8_t value) {
  const ImageView view = frame.view();
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      if (view.data[y * view.stride + x] != value) return false;
    }
  }
  return true;
}

TEST(FrameAssembler, SlowConsumerLosesFramesCountedNeverBlocks) {
  const int width = 40, height = 30;
  const size_t stride = 64;
  FrameAssembler assembler(std::make_shared<FramePool>(width, height, 2), width, height);
  uint64_t dropped = 0;
  auto assemble = [&](uint32_t sensor_sequence, uint8_t value) {
    PaddedSensorFrame in(sensor_sequence, width, height, stride, value);
    FrameAssembler::Assembled out = assembler.Assemble(in.frame);
    dropped += out.dropped;
    return std::move(out.frame);
  };

  // The consumer holds the first two frames: the pool of two is empty.
  Frame first = assemble(500, 10);
  Frame second = assemble(501, 11);
  ASSERT_TRUE(first.valid());
  ASSERT_TRUE(second.valid());
  EXPECT_EQ(first.sequence(), 0U);
  EXPECT_EQ(second.sequence(), 1U);
  EXPECT_EQ(first.timestamp_ns(), 1'000'000'000LL + 500 * 33'333'333LL);
  EXPECT_EQ(first.exposure_us(), 5000);
  EXPECT_DOUBLE_EQ(first.gain(), 2.0);
  EXPECT_EQ(first.view().width, width);
  EXPECT_EQ(first.view().stride, width);  // packed
  EXPECT_TRUE(AllPixelsAre(first, 10));
  EXPECT_TRUE(AllPixelsAre(second, 11));
  EXPECT_EQ(dropped, 0U);

  // Sensor frames 502 and 503 find no buffer: dropped at once, counted.
  EXPECT_FALSE(assemble(502, 12).valid());
  EXPECT_FALSE(assemble(503, 13).valid());
  EXPECT_EQ(dropped, 2U);

  // One buffer comes back; the sensor skipped 504..505 (a pipeline drop): gap counted.
  first.Release();
  Frame next = assemble(506, 16);
  ASSERT_TRUE(next.valid());
  EXPECT_EQ(next.sequence(), 6U);
  EXPECT_TRUE(AllPixelsAre(next, 16));
  EXPECT_TRUE(AllPixelsAre(second, 11));  // a held frame is untouched
  EXPECT_EQ(dropped, 4U);
  // Every sensor frame 500..506 is either delivered (0, 1, 6) or counted as dropped.
  EXPECT_EQ(3U + dropped, 7U);
}

TEST(FrameAssembler, ABadBufferIsAnErrorAndReturnsThePoolBuffer) {
  const int width = 40, height = 30;
  auto pool = std::make_shared<FramePool>(width, height, 2);
  FrameAssembler assembler(pool, width, height);
  PaddedSensorFrame in(7, width, height, 64, 1);
  in.frame.plane = in.frame.plane.first(64 * 10);  // ten rows of thirty
  EXPECT_THROW(assembler.Assemble(in.frame), HardwareError);
  EXPECT_EQ(pool->free_count(), 2);
}

int64_t NowNs(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

TEST(SteadyNsFromBoottimeNs, LandsOnTheSteadyClock) {
  const int64_t boottime = NowNs(CLOCK_BOOTTIME);
  const int64_t steady = SteadyNsFromBoottimeNs(boottime);
  const int64_t steady_now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                 std::chrono::steady_clock::now().time_since_epoch())
                                 .count();
  // Taken within a few microseconds of each other (generous for a loaded machine).
  EXPECT_LE(steady, steady_now);
  EXPECT_LT(steady_now - steady, 50'000'000);
  // An interval is kept exactly.
  EXPECT_NEAR(static_cast<double>(SteadyNsFromBoottimeNs(boottime + 33'333'333) - steady),
              33'333'333.0, 1e6);
}

}  // namespace
}  // namespace mirrorscan::hal::libcamera_stream

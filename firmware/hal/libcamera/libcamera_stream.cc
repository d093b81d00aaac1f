#include "firmware/hal/libcamera/libcamera_stream.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

namespace mirrorscan::hal::libcamera_stream {

std::optional<FormatChoice> ChooseFormat(const std::vector<uint32_t>& supported) {
  auto offered = [&](uint32_t fourcc) {
    return std::find(supported.begin(), supported.end(), fourcc) != supported.end();
  };
  if (offered(kFourccR8)) return FormatChoice{kFourccR8, PixelLayout::kGrey};
  if (offered(kFourccYuv420)) return FormatChoice{kFourccYuv420, PixelLayout::kYuv420};
  for (const uint32_t bayer : {kFourccSrggb8, kFourccSgrbg8, kFourccSgbrg8, kFourccSbggr8}) {
    if (offered(bayer)) return FormatChoice{bayer, PixelLayout::kBayer8};
  }
  return std::nullopt;
}

SensorControls SensorControlsFor(const CameraConfig& config) {
  config.Validate();
  if (config.fps <= 0.0) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera.fps: a libcamera camera needs a frame rate > 0");
  }
  SensorControls controls;
  controls.ae_enable = false;
  controls.exposure_us = config.exposure_us;
  controls.analogue_gain = static_cast<float>(config.gain);
  // Validate() keeps exposure_us <= 1e6 / fps, so the rounded duration still holds it.
  controls.frame_duration_us = std::llround(1e6 / config.fps);
  return controls;
}

void PackPlane(std::span<const uint8_t> plane, size_t stride, int width, int height,
               uint8_t* packed) {
  const size_t row = static_cast<size_t>(width);
  if (stride < row) {
    throw HardwareError(HardwareError::Kind::kIo, "camera: stride " + std::to_string(stride) +
                                                      " is shorter than a row of " +
                                                      std::to_string(width) + " pixels");
  }
  const size_t needed = stride * static_cast<size_t>(height - 1) + row;
  if (height <= 0 || plane.size() < needed) {
    throw HardwareError(HardwareError::Kind::kIo,
                        "camera: buffer plane holds " + std::to_string(plane.size()) +
                            " bytes, a " + std::to_string(width) + "x" + std::to_string(height) +
                            " frame with stride " + std::to_string(stride) + " needs " +
                            std::to_string(needed));
  }
  if (stride == row) {
    std::memcpy(packed, plane.data(), row * static_cast<size_t>(height));
    return;
  }
  for (size_t y = 0; y < static_cast<size_t>(height); ++y) {
    std::memcpy(packed + y * row, plane.data() + y * stride, row);
  }
}

SequenceCounter::Step SequenceCounter::Next(uint32_t sensor_sequence) {
  if (!started_) {
    started_ = true;
    last_sensor_ = sensor_sequence;
    last_ = 0;
    return Step{0, 0};
  }
  // Unsigned difference: the 32-bit counter may wrap (after 4.5 years at 30 fps).
  const uint32_t advance = sensor_sequence - last_sensor_;
  if (advance == 0 || advance > 0x80000000U) {
    throw HardwareError(HardwareError::Kind::kIo, "camera: sensor frame sequence went from " +
                                                      std::to_string(last_sensor_) + " to " +
                                                      std::to_string(sensor_sequence));
  }
  last_sensor_ = sensor_sequence;
  last_ += advance;
  return Step{last_, advance - 1};
}

FrameAssembler::FrameAssembler(std::shared_ptr<FramePool> pool, int width, int height)
    : pool_(std::move(pool)), width_(width), height_(height) {}

FrameAssembler::Assembled FrameAssembler::Assemble(const SensorFrame& frame) {
  const SequenceCounter::Step step = sequence_.Next(frame.sensor_sequence);
  const std::optional<int> buffer = pool_->Acquire();
  if (!buffer) return Assembled{Frame(), step.missed + 1};
  try {
    PackPlane(frame.plane, frame.stride, width_, height_, pool_->pixels(*buffer));
  } catch (...) {
    pool_->Return(*buffer);
    throw;
  }
  return Assembled{
      pool_->MakeFrame(*buffer, step.sequence, frame.timestamp_ns, frame.exposure_us, frame.gain),
      step.missed};
}

int64_t SteadyNsFromBoottimeNs(int64_t boottime_ns) {
  auto now_ns = [](clockid_t clock) {
    timespec ts{};
    clock_gettime(clock, &ts);
    return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  };
  const int64_t monotonic = now_ns(CLOCK_MONOTONIC);
  const int64_t boottime = now_ns(CLOCK_BOOTTIME);
  return boottime_ns - (boottime - monotonic);
}

}  // namespace mirrorscan::hal::libcamera_stream

#pragma once

// The decisions of the libcamera backend that need no camera and no libcamera: which
// pixel format to ask for, what the sensor controls are, how a (strided) buffer becomes a
// packed 8-bit frame, how sensor sequence numbers become frame sequences and drops, and
// which clock the timestamps are on. Pure, so they are tested on their own (also under
// qemu, where libcamera cannot be loaded).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "firmware/hal/camera.h"

namespace mirrorscan::hal::libcamera_stream {

// A DRM fourcc code, as libcamera's PixelFormat::fourcc() gives it.
constexpr uint32_t Fourcc(char a, char b, char c, char d) {
  return static_cast<uint32_t>(static_cast<uint8_t>(a)) |
         static_cast<uint32_t>(static_cast<uint8_t>(b)) << 8 |
         static_cast<uint32_t>(static_cast<uint8_t>(c)) << 16 |
         static_cast<uint32_t>(static_cast<uint8_t>(d)) << 24;
}
inline constexpr uint32_t kFourccR8 = Fourcc('R', '8', ' ', ' ');      // 8-bit grey (mono sensors)
inline constexpr uint32_t kFourccYuv420 = Fourcc('Y', 'U', '1', '2');  // planar, Y plane first
inline constexpr uint32_t kFourccSrggb8 = Fourcc('R', 'G', 'G', 'B');
inline constexpr uint32_t kFourccSgrbg8 = Fourcc('G', 'R', 'B', 'G');
inline constexpr uint32_t kFourccSgbrg8 = Fourcc('G', 'B', 'R', 'G');
inline constexpr uint32_t kFourccSbggr8 = Fourcc('B', 'A', '8', '1');

// What the first plane of a buffer holds. Every choice keeps 8-bit samples, one byte per
// pixel, row after row with the stream's stride: the frame is that plane, packed.
enum class PixelLayout {
  kGrey,    // R8: the grey image itself
  kYuv420,  // YUV420: the Y (luma) plane; U and V follow and are ignored
  kBayer8,  // 8-bit raw Bayer mosaic, taken as is (no demosaicing)
};

struct FormatChoice {
  uint32_t fourcc = 0;
  PixelLayout layout = PixelLayout::kGrey;
};

// The preferred format among those a stream supports (linear fourccs only): R8, then
// YUV420, then 8-bit raw Bayer; nullopt when none is offered.
std::optional<FormatChoice> ChooseFormat(const std::vector<uint32_t>& supported);

// The controls a capture starts with: auto exposure off, exposure and gain fixed, the
// frame duration pinned (min = max) to the configured rate.
struct SensorControls {
  bool ae_enable = false;
  int32_t exposure_us = 0;
  float analogue_gain = 1.0F;
  int64_t frame_duration_us = 0;  // FrameDurationLimits {min, max}, both this
};
// Validates `config` (CameraConfig::Validate) and rejects fps == 0, which only a replay
// can honour (HardwareError kInvalidArgument).
SensorControls SensorControlsFor(const CameraConfig& config);

// Copies the first `height` rows of `width` bytes from `plane` (rows `stride` bytes apart)
// into `packed` (width * height bytes). Throws HardwareError kIo if the stride is shorter
// than a row or the plane is too short for the rows.
void PackPlane(std::span<const uint8_t> plane, size_t stride, int width, int height,
               uint8_t* packed);

// Turns the sensor's frame counter (libcamera's FrameMetadata::sequence, 32 bits, counting
// every frame the sensor produced) into the hal's frame sequence, counting from 0 at the
// first frame after Start(), and the frames skipped since the previous one.
class SequenceCounter {
 public:
  struct Step {
    uint64_t sequence = 0;  // the hal sequence of this frame
    uint64_t missed = 0;    // sensor frames between the previous delivered one and this
  };
  // Throws HardwareError kIo if the counter does not advance (a repeated or backward
  // sequence means the metadata cannot be trusted for drop counting).
  Step Next(uint32_t sensor_sequence);

 private:
  bool started_ = false;
  uint64_t last_ = 0;  // hal sequence of the previous frame
  uint32_t last_sensor_ = 0;
};

// One completed sensor frame, as the backend reads it from a libcamera request.
struct SensorFrame {
  uint32_t sensor_sequence = 0;    // FrameMetadata::sequence
  std::span<const uint8_t> plane;  // the mapped first plane
  size_t stride = 0;               // bytes between rows of `plane`
  int64_t timestamp_ns = 0;        // steady clock
  int exposure_us = 0;
  double gain = 1.0;
};

// Turns sensor frames into frames of the hal pool: sequence from the sensor's counter,
// pixels packed into a free pool buffer, drops counted for counter gaps and for frames
// that found every buffer with the consumer. Never blocks.
class FrameAssembler {
 public:
  FrameAssembler(std::shared_ptr<FramePool> pool, int width, int height);

  struct Assembled {
    Frame frame;           // invalid when this frame is dropped for want of a buffer
    uint64_t dropped = 0;  // frames lost since the previous call, this one included
  };
  // Throws HardwareError kIo (PackPlane, SequenceCounter); the pool buffer is returned.
  Assembled Assemble(const SensorFrame& frame);

 private:
  std::shared_ptr<FramePool> pool_;
  int width_, height_;
  SequenceCounter sequence_;
};

// libcamera's SensorTimestamp is defined on CLOCK_BOOTTIME; the hal's timestamps are on
// the steady clock (CLOCK_MONOTONIC). The two differ by the time spent in suspend, read
// now from both clocks.
int64_t SteadyNsFromBoottimeNs(int64_t boottime_ns);

}  // namespace mirrorscan::hal::libcamera_stream

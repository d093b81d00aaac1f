#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/peaks/peaks.h"
#include "firmware/hal/clock.h"
#include "firmware/hal/hardware_error.h"

namespace mirrorscan::hal {

// What a camera is asked to deliver. Backends may reject settings they cannot honour
// (e.g. a size other than the sensor's) with HardwareError kInvalidArgument.
struct CameraConfig {
  int width = 1024;
  int height = 768;
  // Frames per second. 0 = as fast as the consumer releases buffers (replay only; a live
  // camera rejects it).
  double fps = 30.0;
  int exposure_us = 5000;  // > 0 and at most one frame period
  double gain = 1.0;       // analogue gain, 1..64
  int buffer_count = 4;    // the fixed frame pool, 2..64 buffers

  // Throws HardwareError kInvalidArgument "camera.<key>: problem".
  void Validate() const;
};

class FramePool;

// One captured 8-bit grayscale frame. Move-only: it owns one buffer of its camera's pool
// and hands it back when destroyed or Release()d (libcamera's request recycling). The
// pixels stay valid until then, even if the camera is stopped or destroyed meanwhile.
class Frame {
 public:
  Frame() = default;
  Frame(Frame&& other) noexcept;
  Frame& operator=(Frame&& other) noexcept;
  Frame(const Frame&) = delete;
  Frame& operator=(const Frame&) = delete;
  ~Frame() { Release(); }

  bool valid() const { return pool_ != nullptr; }
  // Borrowed pixels, row-major, stride = width; for the peak extractor.
  ImageView view() const { return view_; }
  // Counts every frame the sensor exposed since Start(), from 0; a dropped frame leaves a
  // gap, so consumers can tell how many they missed.
  uint64_t sequence() const { return sequence_; }
  // Start of exposure, steady clock, nanoseconds.
  int64_t timestamp_ns() const { return timestamp_ns_; }
  int exposure_us() const { return exposure_us_; }
  double gain() const { return gain_; }

  // Returns the buffer to the camera now; the frame becomes invalid.
  void Release();

 private:
  friend class FramePool;
  std::shared_ptr<FramePool> pool_;
  int buffer_ = -1;
  ImageView view_;
  uint64_t sequence_ = 0;
  int64_t timestamp_ns_ = 0;
  int exposure_us_ = 0;
  double gain_ = 0.0;
};

// A grayscale camera, modelled on libcamera: a fixed pool of buffers circulates between
// the camera and the consumer. The camera fills a free buffer per frame and passes it to
// the frame callback; the consumer releases it (by dropping the Frame) when done. When no
// buffer is free the camera drops that frame and counts it (dropped()): a slow consumer
// never blocks the producer, it loses frames.
//
// Callbacks run on the camera's own thread and must only enqueue (move the Frame to a
// queue and return); they must not call Stop().
//
// Errors: calls throw HardwareError (kInvalidArgument for bad settings or a call in the
// wrong state, kIo when the device or file cannot be used). A failure while streaming
// ends the stream and is reported once through the end callback.
//
// Threading: Configure/Start/Stop from one controlling thread; dropped() and
// Frame::Release() from any thread.
class Camera {
 public:
  using FrameCallback = std::function<void(Frame frame)>;
  // Called once on the camera's thread when the stream ends by itself: at the end of a
  // non-looping replay (error == nullptr) or after a failure. Never called by Stop().
  using EndCallback = std::function<void(const HardwareError* error)>;

  virtual ~Camera() = default;

  // Validates and applies the settings; only while stopped.
  virtual void Configure(const CameraConfig& config) = 0;
  // Starts streaming with the configured settings (Configure() first).
  virtual void Start(FrameCallback on_frame, EndCallback on_end = {}) = 0;
  // Stops streaming and joins the camera's thread: no callback runs once it returns.
  // Prompt (within one frame's work), idempotent, never throws.
  virtual void Stop() = 0;

  // From Start() until Stop(), also after the stream ended by itself (call Stop() before
  // starting again).
  virtual bool streaming() const = 0;
  // Frames lost since Start() because no buffer was free (or injected by a simulation).
  virtual uint64_t dropped() const = 0;
  virtual const CameraConfig& config() const = 0;
  // The camera's own time, steady nanoseconds: how far its sensor has got. What a stall
  // watchdog measures a camera's silence in. A real sensor runs in real time, whatever
  // the host is doing, so the default is the steady clock; a camera whose frames cost
  // host time to make (ThreadedCamera) overrides it. Any thread.
  virtual int64_t clock_ns() const { return SteadyNowNs(); }
};

// The buffer pool behind Frame; shared by the camera and its outstanding frames.
class FramePool : public std::enable_shared_from_this<FramePool> {
 public:
  FramePool(int width, int height, int count);

  // A free buffer, or nullopt when all are with the consumer. Never blocks.
  std::optional<int> Acquire();
  // Blocks until a buffer is free or `stop` becomes true (then nullopt).
  std::optional<int> AcquireWait(const std::atomic<bool>& stop);
  // Wakes AcquireWait() so it can look at its stop flag.
  void Wake();
  uint8_t* pixels(int buffer) { return buffers_[buffer].data(); }
  int free_count() const;
  // Wraps a filled buffer into a Frame that returns it on release.
  Frame MakeFrame(int buffer, uint64_t sequence, int64_t timestamp_ns, int exposure_us,
                  double gain);
  // Hands back a buffer that was acquired but is not delivered.
  void Return(int buffer);

 private:
  int width_, height_;
  std::vector<std::vector<uint8_t>> buffers_;
  mutable std::mutex mutex_;
  std::condition_variable freed_;
  std::vector<int> free_;
};

// The common engine of cameras that make frames on their own thread: pacing at the
// configured fps (or as fast as buffers come back when fps == 0), the pool, drop
// counting, Start/Stop. Backends fill pixels.
class ThreadedCamera : public Camera {
 public:
  ~ThreadedCamera() override;  // Backends must call Stop() in their own destructor.

  void Configure(const CameraConfig& config) final;
  void Start(FrameCallback on_frame, EndCallback on_end = {}) final;
  void Stop() final;
  bool streaming() const final { return thread_.joinable(); }
  uint64_t dropped() const final { return dropped_.load(); }
  const CameraConfig& config() const final { return config_; }
  // The simulated sensor's time: it runs while the camera thread waits for its next
  // exposure, up to that exposure's scheduled time, and stands still from then until the
  // thread waits again, i.e. while the host is late to run the thread or busy making the
  // frame (a renderer, a file read: work a real sensor does not take from the host). On a
  // busy host the frames come later and the clock falls behind the steady clock by as
  // much; while stalled (SetStalled) no frame is in the making and the clock keeps up
  // with the steady clock. Any thread.
  int64_t clock_ns() const final;

  // Fault injection for these simulated cameras (any thread, any time): while stalled the
  // camera delivers nothing, takes no sequence number and counts no drop (a hung sensor:
  // only a watchdog notices), and its clock runs. false resumes.
  void SetStalled(bool stalled) { stalled_ = stalled; }

 protected:
  enum class Produced {
    kFrame,  // the buffer holds the next frame: deliver it
    kSkip,   // nothing this period (a stalled sensor); the sequence does not advance
    kDrop,   // the frame is lost (counted in dropped()); sequence advances
    kEnd,    // end of stream (the end callback gets nullptr)
  };

  // Backend checks beyond CameraConfig::Validate(); throw HardwareError.
  virtual void CheckConfig(const CameraConfig& config) { (void)config; }
  // Prepares streaming (open files, ...); throws HardwareError. On the caller's thread.
  virtual void BeginStream() {}
  // Decides, before a buffer is taken, what happens to frame `sequence`: kFrame goes on
  // to Produce(); kSkip, kDrop and kEnd act at once and cost no buffer (an injected
  // drop or a stall). Runs on the camera thread. Default: kFrame.
  virtual Produced Plan(uint64_t sequence) {
    (void)sequence;
    return Produced::kFrame;
  }
  // Fills width*height pixels (stride = width) with frame `sequence` exposed at
  // `timestamp_ns`. Runs on the camera thread; throws HardwareError to end the stream.
  virtual Produced Produce(uint64_t sequence, int64_t timestamp_ns, uint8_t* pixels) = 0;

  // True once Stop() has been requested; long Produce() calls may poll it.
  bool stop_requested() const { return stop_.load(); }

 private:
  void Run();

  CameraConfig config_;
  bool configured_ = false;
  std::shared_ptr<FramePool> pool_;
  FrameCallback on_frame_;
  EndCallback on_end_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  std::atomic<uint64_t> dropped_{0};
  std::atomic<bool> stalled_{false};

  // clock_ns(): camera time = base + (min(now, runs_until) - since), never below base.
  void ClockRunUntil(int64_t until_ns);  // the thread starts waiting for `until_ns`
  void ClockStop();                      // the thread is working
  void ClockCatchUp();                   // ... on no frame: the time since the stop counts
  mutable std::mutex clock_mutex_;
  int64_t clock_base_ns_ = 0;    // the camera's time at clock_since_ns_
  int64_t clock_since_ns_ = 0;   // steady time the current run began
  int64_t clock_until_ns_ = 0;   // steady time the current run ends (== since: stopped)
  int64_t clock_frozen_ns_ = 0;  // steady time the clock last stood still from
};

}  // namespace mirrorscan::hal

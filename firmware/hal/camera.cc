#include "firmware/hal/camera.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <utility>

namespace mirrorscan::hal {
namespace {

[[noreturn]] void Invalid(const std::string& key, const std::string& problem) {
  throw HardwareError(HardwareError::Kind::kInvalidArgument, "camera." + key + ": " + problem);
}

}  // namespace

void CameraConfig::Validate() const {
  if (width < 16 || width > 16384) Invalid("width", "must be 16..16384");
  if (height < 16 || height > 16384) Invalid("height", "must be 16..16384");
  if (!std::isfinite(fps) || fps < 0.0 || fps > 1000.0) Invalid("fps", "must be 0..1000");
  if (exposure_us <= 0) Invalid("exposure_us", "must be > 0");
  if (fps > 0.0 && exposure_us > 1e6 / fps) {
    Invalid("exposure_us", "must not exceed the frame period (" +
                               std::to_string(static_cast<int>(1e6 / fps)) + " us)");
  }
  if (!std::isfinite(gain) || gain < 1.0 || gain > 64.0) Invalid("gain", "must be 1..64");
  if (buffer_count < 2 || buffer_count > 64) Invalid("buffer_count", "must be 2..64");
}

// ---------------------------------------------------------------------------------------
// Frame

Frame::Frame(Frame&& other) noexcept { *this = std::move(other); }

Frame& Frame::operator=(Frame&& other) noexcept {
  if (this != &other) {
    Release();
    pool_ = std::move(other.pool_);
    buffer_ = std::exchange(other.buffer_, -1);
    view_ = std::exchange(other.view_, ImageView{});
    sequence_ = other.sequence_;
    timestamp_ns_ = other.timestamp_ns_;
    exposure_us_ = other.exposure_us_;
    gain_ = other.gain_;
  }
  return *this;
}

void Frame::Release() {
  if (pool_) pool_->Return(buffer_);
  pool_.reset();
  buffer_ = -1;
  view_ = ImageView{};
}

// ---------------------------------------------------------------------------------------
// FramePool

FramePool::FramePool(int width, int height, int count)
    : width_(width), height_(height), buffers_(static_cast<size_t>(count)) {
  for (int i = 0; i < count; ++i) {
    buffers_[static_cast<size_t>(i)].resize(static_cast<size_t>(width) * height);
    free_.push_back(count - 1 - i);
  }
}

std::optional<int> FramePool::Acquire() {
  std::lock_guard lock(mutex_);
  if (free_.empty()) return std::nullopt;
  const int b = free_.back();
  free_.pop_back();
  return b;
}

std::optional<int> FramePool::AcquireWait(const std::atomic<bool>& stop) {
  std::unique_lock lock(mutex_);
  freed_.wait(lock, [&] { return stop.load() || !free_.empty(); });
  if (stop.load()) return std::nullopt;
  const int b = free_.back();
  free_.pop_back();
  return b;
}

void FramePool::Wake() {
  { std::lock_guard lock(mutex_); }
  freed_.notify_all();
}

int FramePool::free_count() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(free_.size());
}

Frame FramePool::MakeFrame(int buffer, uint64_t sequence, int64_t timestamp_ns, int exposure_us,
                           double gain) {
  Frame f;
  f.pool_ = shared_from_this();
  f.buffer_ = buffer;
  f.view_ = ImageView{pixels(buffer), width_, height_, width_};
  f.sequence_ = sequence;
  f.timestamp_ns_ = timestamp_ns;
  f.exposure_us_ = exposure_us;
  f.gain_ = gain;
  return f;
}

void FramePool::Return(int buffer) {
  {
    std::lock_guard lock(mutex_);
    free_.push_back(buffer);
  }
  freed_.notify_all();
}

// ---------------------------------------------------------------------------------------
// ThreadedCamera

ThreadedCamera::~ThreadedCamera() { Stop(); }

void ThreadedCamera::Configure(const CameraConfig& config) {
  if (streaming()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera: Configure() while streaming; Stop() first");
  }
  config.Validate();
  CheckConfig(config);
  config_ = config;
  configured_ = true;
}

void ThreadedCamera::Start(FrameCallback on_frame, EndCallback on_end) {
  if (streaming()) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument, "camera: already streaming");
  }
  if (!configured_) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument,
                        "camera: Start() before Configure()");
  }
  if (!on_frame) {
    throw HardwareError(HardwareError::Kind::kInvalidArgument, "camera: no frame callback");
  }
  BeginStream();
  // A fresh pool each time: frames still held from an earlier stream keep their own.
  pool_ = std::make_shared<FramePool>(config_.width, config_.height, config_.buffer_count);
  on_frame_ = std::move(on_frame);
  on_end_ = std::move(on_end);
  dropped_ = 0;
  stop_ = false;
  {
    std::lock_guard lock(clock_mutex_);
    clock_base_ns_ = clock_since_ns_ = clock_until_ns_ = clock_frozen_ns_ = SteadyNowNs();
  }
  thread_ = std::thread([this] { Run(); });
}

int64_t ThreadedCamera::clock_ns() const {
  const int64_t now_ns = SteadyNowNs();
  std::lock_guard lock(clock_mutex_);
  return clock_base_ns_ + std::max<int64_t>(0, std::min(now_ns, clock_until_ns_) - clock_since_ns_);
}

void ThreadedCamera::ClockRunUntil(int64_t until_ns) {
  const int64_t now_ns = SteadyNowNs();
  std::lock_guard lock(clock_mutex_);
  clock_since_ns_ = now_ns;
  clock_until_ns_ = until_ns;
}

void ThreadedCamera::ClockStop() {
  const int64_t now_ns = SteadyNowNs();
  std::lock_guard lock(clock_mutex_);
  const int64_t frozen_ns = std::max(clock_since_ns_, std::min(now_ns, clock_until_ns_));
  clock_base_ns_ += frozen_ns - clock_since_ns_;
  clock_since_ns_ = clock_until_ns_ = now_ns;
  clock_frozen_ns_ = frozen_ns;
}

void ThreadedCamera::ClockCatchUp() {
  const int64_t now_ns = SteadyNowNs();
  std::lock_guard lock(clock_mutex_);
  clock_base_ns_ += std::max<int64_t>(0, now_ns - clock_frozen_ns_);
  clock_since_ns_ = clock_until_ns_ = clock_frozen_ns_ = now_ns;
}

void ThreadedCamera::Stop() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(wake_mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (pool_) pool_->Wake();
  thread_.join();
  on_frame_ = nullptr;
  on_end_ = nullptr;
}

void ThreadedCamera::Run() {
  using Clock = std::chrono::steady_clock;
  const bool paced = config_.fps > 0.0;
  const auto period = paced ? std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(1.0 / config_.fps))
                            : Clock::duration::zero();
  auto next = Clock::now();
  uint64_t sequence = 0;
  auto end = [&](const HardwareError* error) {
    if (on_end_) on_end_(error);
  };
  try {
    while (!stop_.load()) {
      if (paced) {
        ClockRunUntil(
            std::chrono::duration_cast<std::chrono::nanoseconds>(next.time_since_epoch()).count());
        std::unique_lock lock(wake_mutex_);
        const bool stopping = wake_.wait_until(lock, next, [&] { return stop_.load(); });
        lock.unlock();
        ClockStop();
        if (stopping) break;
      }
      // The sensor keeps its rhythm; a late frame starts the next period from now. Unpaced
      // (fps 0), a frame is exposed once a buffer is free.
      auto exposed = next;
      if (paced) next = std::max(next + period, Clock::now());

      if (stalled_.load()) {
        ClockCatchUp();  // no frame is in the making: the thread's lateness is the sensor's time
        if (!paced) {    // nothing paces an unpaced camera's stall: do not spin
          std::unique_lock lock(wake_mutex_);
          wake_.wait_for(lock, std::chrono::milliseconds(1), [&] { return stop_.load(); });
        }
        continue;
      }
      const Produced plan = Plan(sequence);
      if (plan == Produced::kSkip) continue;
      if (plan == Produced::kDrop) {
        ++dropped_;
        ++sequence;
        continue;
      }
      if (plan == Produced::kEnd) {
        end(nullptr);
        return;
      }

      std::optional<int> buffer;
      if (paced) {
        buffer = pool_->Acquire();
      } else {
        // Unpaced, the sensor waits for the consumer: its time runs meanwhile.
        ClockRunUntil(INT64_MAX);
        buffer = pool_->AcquireWait(stop_);
        ClockStop();
      }
      if (!buffer) {
        if (stop_.load()) break;
        ++dropped_;  // every buffer is with the consumer: the sensor's frame is lost
        ++sequence;
        continue;
      }
      if (!paced) exposed = Clock::now();
      const int64_t timestamp_ns =
          std::chrono::duration_cast<std::chrono::nanoseconds>(exposed.time_since_epoch()).count();
      Produced produced;
      try {
        produced = Produce(sequence, timestamp_ns, pool_->pixels(*buffer));
      } catch (...) {
        pool_->Return(*buffer);
        throw;
      }
      switch (produced) {
        case Produced::kFrame:
          on_frame_(
              pool_->MakeFrame(*buffer, sequence, timestamp_ns, config_.exposure_us, config_.gain));
          ++sequence;
          break;
        case Produced::kSkip:
          pool_->Return(*buffer);
          break;
        case Produced::kDrop:
          pool_->Return(*buffer);
          ++dropped_;
          ++sequence;
          break;
        case Produced::kEnd:
          pool_->Return(*buffer);
          end(nullptr);
          return;
      }
    }
  } catch (const HardwareError& e) {
    end(&e);
  } catch (const std::exception& e) {
    const HardwareError error(HardwareError::Kind::kIo, std::string("camera: ") + e.what());
    end(&error);
  }
}

}  // namespace mirrorscan::hal

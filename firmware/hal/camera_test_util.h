#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string>

#include "firmware/hal/camera.h"

namespace mirrorscan::hal::testing {

// What a consumer does with the camera's callbacks: enqueue, nothing more.
class FrameQueue {
 public:
  Camera::FrameCallback OnFrame() {
    return [this](Frame f) {
      {
        std::lock_guard lock(mutex_);
        frames_.push_back(std::move(f));
      }
      cv_.notify_all();
    };
  }
  Camera::EndCallback OnEnd() {
    return [this](const HardwareError* e) {
      {
        std::lock_guard lock(mutex_);
        ended_ = true;
        if (e) error_ = e->what();
      }
      cv_.notify_all();
    };
  }
  // The next frame, or an invalid one after `timeout`.
  Frame Pop(std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [&] { return !frames_.empty(); })) return Frame();
    Frame f = std::move(frames_.front());
    frames_.pop_front();
    return f;
  }
  bool WaitEnd(std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return ended_; });
  }
  size_t size() {
    std::lock_guard lock(mutex_);
    return frames_.size();
  }
  std::optional<std::string> error() {
    std::lock_guard lock(mutex_);
    return error_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Frame> frames_;
  bool ended_ = false;
  std::optional<std::string> error_;
};

// Polls `done` until it holds or `timeout` passes.
template <typename F>
bool WaitFor(F done, std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace mirrorscan::hal::testing

#pragma once

// A ScanControl for tests of the device API: StartScan writes a synthetic scan through the
// real ScanStore on its own thread (frames at a set pace, progress events, a footer), so
// the API's streams, downloads and checksums are exercised against real archive files.
// The product never uses it; the sequencer (firmware/scan) is the real implementation.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "firmware/scan/scan_control.h"
#include "firmware/store/scan_store.h"

namespace mirrorscan::service {

class TestScanControl : public scan::ScanControl {
 public:
  struct Options {
    int frames = 40;
    std::chrono::milliseconds frame_interval{5};
    int peaks_per_frame = 200;
  };

  TestScanControl(store::ScanStore& store, Options options) : store_(store), options_(options) {}
  ~TestScanControl() override { Join(); }

  std::string StartScan(std::string_view origin) override {
    std::unique_lock lock(mutex_);
    if (running_)
      throw scan::ScanControlError(scan::ScanControlError::Kind::kBusy, "a scan is running");
    if (thread_.joinable()) thread_.join();
    auto handle = store_.BeginScan({{"origin", std::string(origin)}, {"board", "test"}});
    const std::string id = handle->id();
    running_ = true;
    status_ = scan::ScanStatus{};
    status_.state = scan::SequencerState::kSweeping;
    status_.scan_id = id;
    Publish(scan::ScanEvent::Type::kState);
    thread_ = std::thread([this, h = std::move(handle)]() mutable { Sweep(std::move(h)); });
    return id;
  }

  void Abort(std::string_view) override { abort_ = true; }

  scan::ScanStatus Status() const override {
    std::lock_guard lock(mutex_);
    return status_;
  }

  int Subscribe(Listener listener) override {
    std::lock_guard lock(mutex_);
    listeners_[next_handle_] = std::move(listener);
    return next_handle_++;
  }

  void Unsubscribe(int handle) override {
    std::lock_guard lock(mutex_);
    listeners_.erase(handle);
  }

  int listeners() const {
    std::lock_guard lock(mutex_);
    return static_cast<int>(listeners_.size());
  }

  scan::CapturedFrame Capture(const std::string& camera, bool lasers_on) override {
    std::lock_guard lock(mutex_);
    if (running_)
      throw scan::ScanControlError(scan::ScanControlError::Kind::kBusy, "a scan is running");
    scan::CapturedFrame frame;
    frame.camera = camera;
    frame.width = 64;
    frame.height = 48;
    frame.lasers_on = lasers_on;
    frame.pixels.resize(64 * 48);
    for (size_t i = 0; i < frame.pixels.size(); ++i) {
      frame.pixels[i] = static_cast<uint8_t>((i % 64) * 4 + (lasers_on ? 1 : 0));
    }
    return frame;
  }

  // Waits until the running scan (if any) has finished.
  void Join() {
    std::thread thread;
    {
      std::lock_guard lock(mutex_);
      thread.swap(thread_);
    }
    if (thread.joinable()) thread.join();
  }

 private:
  void Publish(scan::ScanEvent::Type type) {  // mutex_ held
    for (auto& [handle, listener] : listeners_) listener(scan::ScanEvent{type, status_});
  }

  void Sweep(std::unique_ptr<store::ScanHandle> handle) {
    for (int i = 0; i < options_.frames && !abort_; ++i) {
      FrameRecord frame;
      frame.camera = static_cast<uint8_t>(i % 2);
      frame.lasers_on = true;
      frame.sequence = static_cast<uint32_t>(i);
      frame.timestamp_ns = int64_t{i} * 33'000'000;
      frame.slide_position_mm = i * 2.5;
      for (int k = 0; k < options_.peaks_per_frame; ++k) {
        Peak peak;
        peak.u = static_cast<uint16_t>(k);
        peak.v = 100.0f + static_cast<float>(i) + 0.25f * static_cast<float>(k % 4);
        peak.intensity = static_cast<float>(k % 255);
        peak.width = 3.0f;
        frame.peaks.push_back(peak);
      }
      handle->AppendFrame(frame);
      {
        std::lock_guard lock(mutex_);
        status_.frames = handle->frames();
        status_.peaks = handle->peaks();
        status_.progress = static_cast<double>(i + 1) / options_.frames;
        status_.position_mm = frame.slide_position_mm;
        Publish(scan::ScanEvent::Type::kProgress);
      }
      std::this_thread::sleep_for(options_.frame_interval);
    }
    const bool aborted = abort_.exchange(false);
    handle->Finish(aborted ? nlohmann::json{{"status", "aborted"}, {"reason", "test abort"}}
                           : nlohmann::json{{"status", "complete"}});
    std::lock_guard lock(mutex_);
    status_.state = aborted ? scan::SequencerState::kAborted : scan::SequencerState::kDone;
    status_.progress = aborted ? status_.progress : 1.0;
    running_ = false;
    Publish(scan::ScanEvent::Type::kState);
  }

  store::ScanStore& store_;
  const Options options_;
  mutable std::mutex mutex_;
  std::thread thread_;
  bool running_ = false;
  std::atomic<bool> abort_{false};
  scan::ScanStatus status_;
  std::map<int, Listener> listeners_;
  int next_handle_ = 0;
};

}  // namespace mirrorscan::service

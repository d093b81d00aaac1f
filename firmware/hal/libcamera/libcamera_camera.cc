// The libcamera backend of hal::Camera. Built only into the dlopen'ed module
// (libmirrorscan_camera_libcamera.so); see libcamera_loader.h for why.

#include <sys/mman.h>

#include <libcamera/libcamera.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "firmware/hal/libcamera/libcamera_module_abi.h"
#include "firmware/hal/libcamera/libcamera_stream.h"

namespace mirrorscan::hal {
namespace {

namespace lc = ::libcamera;
using libcamera_stream::FormatChoice;

[[noreturn]] void Fail(HardwareError::Kind kind, const std::string& message) {
  throw HardwareError(kind, message);
}

std::string ErrnoText(int negative_errno) { return std::strerror(-negative_errno); }

std::string JoinIds(const std::vector<std::string>& ids) {
  if (ids.empty()) return "none";
  std::string joined;
  for (const std::string& id : ids) joined += (joined.empty() ? "" : ", ") + ("\"" + id + "\"");
  return joined;
}

// libcamera allows one CameraManager per process. It starts on first use and is shared
// by the cameras, so it outlives every camera it made.
std::shared_ptr<lc::CameraManager> Manager() {
  static std::mutex mutex;
  static std::shared_ptr<lc::CameraManager> manager;
  std::lock_guard lock(mutex);
  if (!manager) {
    auto started = std::make_shared<lc::CameraManager>();
    if (const int ret = started->start(); ret < 0) {
      Fail(HardwareError::Kind::kIo, "libcamera: camera manager did not start: " + ErrnoText(ret));
    }
    manager = std::move(started);
  }
  return manager;
}

std::vector<std::string> CameraIds(const lc::CameraManager& manager) {
  std::vector<std::string> ids;
  for (const std::shared_ptr<lc::Camera>& camera : manager.cameras()) ids.push_back(camera->id());
  return ids;
}

// The linear 8-bit formats a stream offers, as fourccs.
std::vector<uint32_t> LinearFourccs(const lc::StreamConfiguration& stream) {
  std::vector<uint32_t> fourccs;
  for (const lc::PixelFormat& format : stream.formats().pixelformats()) {
    if (format.modifier() == 0) fourccs.push_back(format.fourcc());
  }
  return fourccs;
}

std::string FormatList(const lc::StreamConfiguration& stream) {
  std::string list;
  for (const lc::PixelFormat& format : stream.formats().pixelformats()) {
    list += (list.empty() ? "" : " ") + format.toString();
  }
  return list.empty() ? "none" : list;
}

class LibcameraCamera final : public Camera {
 public:
  LibcameraCamera(std::shared_ptr<lc::CameraManager> manager, std::shared_ptr<lc::Camera> camera)
      : manager_(std::move(manager)), camera_(std::move(camera)) {}

  ~LibcameraCamera() override {
    Stop();
    camera_->release();
  }

  void Configure(const CameraConfig& config) override {
    if (streaming()) {
      Fail(HardwareError::Kind::kInvalidArgument,
           Name() + ": Configure() while streaming; Stop() first");
    }
    const libcamera_stream::SensorControls controls = libcamera_stream::SensorControlsFor(config);
    // Fixed exposure, gain and rate are what the peak extractor's thresholds assume, so
    // a camera that cannot fix them is refused rather than left on auto. Their ranges
    // depend on the sensor mode, so Start() checks them once the stream is configured.
    RequireControl(lc::controls::ExposureTime, "exposure_us");
    RequireControl(lc::controls::AnalogueGain, "gain");
    RequireControl(lc::controls::FrameDurationLimits, "fps");
    config_ = config;
    controls_ = controls;
    configured_ = true;
  }

  void Start(FrameCallback on_frame, EndCallback on_end) override {
    if (streaming()) Fail(HardwareError::Kind::kInvalidArgument, Name() + ": already streaming");
    if (!configured_) {
      Fail(HardwareError::Kind::kInvalidArgument, Name() + ": Start() before Configure()");
    }
    if (!on_frame) Fail(HardwareError::Kind::kInvalidArgument, Name() + ": no frame callback");
    try {
      ConfigureStream();
      CheckRange(lc::controls::ExposureTime, "exposure_us", controls_.exposure_us, "us");
      CheckRange(lc::controls::AnalogueGain, "gain", controls_.analogue_gain, "");
      CheckRange(lc::controls::FrameDurationLimits, "fps", controls_.frame_duration_us,
                 "us frame duration");
      AllocateBuffers();
      camera_->requestCompleted.connect(this, &LibcameraCamera::OnRequestCompleted);
      camera_->disconnected.connect(this, &LibcameraCamera::OnDisconnected);
      {
        std::lock_guard lock(mutex_);
        completed_.clear();
        stop_ = false;
        disconnected_ = false;
      }
      // A fresh pool each time: frames still held from an earlier stream keep their own.
      assembler_.emplace(
          std::make_shared<FramePool>(config_.width, config_.height, config_.buffer_count),
          config_.width, config_.height);
      dropped_ = 0;
      on_frame_ = std::move(on_frame);
      on_end_ = std::move(on_end);

      lc::ControlList start_controls(camera_->controls());
      if (camera_->controls().count(&lc::controls::AeEnable) != 0) {
        start_controls.set(lc::controls::AeEnable, controls_.ae_enable);
      }
      start_controls.set(lc::controls::ExposureTime, controls_.exposure_us);
      start_controls.set(lc::controls::AnalogueGain, controls_.analogue_gain);
      start_controls.set(lc::controls::FrameDurationLimits,
                         {controls_.frame_duration_us, controls_.frame_duration_us});
      if (const int ret = camera_->start(&start_controls); ret < 0) {
        Fail(HardwareError::Kind::kIo, Name() + ": start failed: " + ErrnoText(ret));
      }
      camera_started_ = true;
      for (const std::unique_ptr<lc::Request>& request : requests_) {
        if (const int ret = camera_->queueRequest(request.get()); ret < 0) {
          Fail(HardwareError::Kind::kIo, Name() + ": queueing a request failed: " + ErrnoText(ret));
        }
      }
    } catch (...) {
      Release();
      throw;
    }
    worker_ = std::thread([this] { Run(); });
  }

  void Stop() override {
    if (!worker_.joinable()) return;
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    worker_.join();
    Release();
  }

  bool streaming() const override { return worker_.joinable(); }
  uint64_t dropped() const override { return dropped_.load(); }
  const CameraConfig& config() const override { return config_; }

 private:
  std::string Name() const { return "camera \"" + camera_->id() + "\""; }

  // The camera must offer `control` (HardwareError kInvalidArgument "camera.<key>: ...").
  template <typename T>
  void RequireControl(const lc::Control<T>& control, const std::string& key) const {
    if (camera_->controls().count(&control) == 0) {
      Fail(HardwareError::Kind::kInvalidArgument,
           "camera." + key + ": " + Name() + " has no " + control.name() + " control");
    }
  }

  // `value` must lie in the range the configured camera reports for `control`.
  template <typename T, typename V>
  void CheckRange(const lc::Control<T>& control, const std::string& key, V value,
                  const std::string& unit) const {
    const auto it = camera_->controls().find(&control);
    if (it == camera_->controls().end()) return;  // Configure() required it
    using Scalar = std::conditional_t<std::is_same_v<T, lc::Span<const int64_t, 2>>, int64_t, T>;
    const lc::ControlInfo& info = it->second;
    // A range entry may be unset, an array or of another type; only a matching scalar bounds.
    auto bound = [](const lc::ControlValue& v) -> std::optional<Scalar> {
      if (v.isArray() || v.type() != lc::details::control_type<Scalar>::value) {
        return std::nullopt;
      }
      return v.get<Scalar>();
    };
    const std::optional<Scalar> min = bound(info.min());
    const std::optional<Scalar> max = bound(info.max());
    if ((min && static_cast<Scalar>(value) < *min) || (max && static_cast<Scalar>(value) > *max)) {
      Fail(HardwareError::Kind::kInvalidArgument,
           "camera." + key + ": " + Name() + " accepts " + control.name() + " " + info.toString() +
               " at " + std::to_string(config_.width) + "x" + std::to_string(config_.height) +
               ", asked for " + std::to_string(value) + (unit.empty() ? "" : " " + unit));
    }
  }

  // Picks role and format and applies the size. Candidates go in order of preference
  // (libcamera_stream::ChooseFormat per role; a better layout first, the processed
  // Viewfinder stream before Raw on a tie); the first that takes the size exactly wins.
  // A raw stream, for instance, only offers the sensor's own modes.
  void ConfigureStream() {
    struct Candidate {
      lc::StreamRole role;
      std::unique_ptr<lc::CameraConfiguration> config;
      FormatChoice format;
    };
    std::vector<Candidate> candidates;
    std::string offered;
    for (const lc::StreamRole role : {lc::StreamRole::Viewfinder, lc::StreamRole::Raw}) {
      std::unique_ptr<lc::CameraConfiguration> config = camera_->generateConfiguration({role});
      if (!config || config->empty()) continue;
      offered += (offered.empty() ? "" : "; ") + FormatList(config->at(0));
      if (const std::optional<FormatChoice> format =
              libcamera_stream::ChooseFormat(LinearFourccs(config->at(0)))) {
        candidates.push_back({role, std::move(config), *format});
      }
    }
    if (candidates.empty()) {
      Fail(HardwareError::Kind::kInvalidArgument,
           Name() + " offers no 8-bit grey, YUV420 or 8-bit raw format (offers: " +
               (offered.empty() ? "nothing" : offered) + ")");
    }
    std::stable_sort(
        candidates.begin(), candidates.end(),
        [](const Candidate& a, const Candidate& b) { return a.format.layout < b.format.layout; });

    const lc::Size wanted_size(static_cast<unsigned>(config_.width),
                               static_cast<unsigned>(config_.height));
    std::string refusals;
    for (Candidate& candidate : candidates) {
      lc::StreamConfiguration& stream = candidate.config->at(0);
      const lc::PixelFormat wanted(candidate.format.fourcc);
      stream.pixelFormat = wanted;
      stream.size = wanted_size;
      // stream.bufferCount stays the pipeline's own: frames are copied out at once, so
      // libcamera needs only enough buffers to keep the sensor fed, while the consumer's
      // slack is the hal pool (CameraConfig::buffer_count).
      const std::string tried =
          std::string(candidate.role == lc::StreamRole::Raw ? "raw" : "viewfinder") + " " +
          wanted.toString() + " " + wanted_size.toString();
      if (candidate.config->validate() == lc::CameraConfiguration::Invalid) {
        refusals += (refusals.empty() ? "" : "; ") + tried + ": invalid";
        continue;
      }
      if (stream.pixelFormat != wanted || stream.size != wanted_size) {
        std::string sizes;
        for (const lc::Size& size : stream.formats().sizes(wanted)) {
          sizes += (sizes.empty() ? "" : " ") + size.toString();
        }
        refusals += (refusals.empty() ? "" : "; ") + tried + ": would give " + stream.toString() +
                    " (sizes: " + (sizes.empty() ? "none listed" : sizes) + ")";
        continue;
      }
      if (const int ret = camera_->configure(candidate.config.get()); ret < 0) {
        Fail(HardwareError::Kind::kIo,
             Name() + ": configure " + tried + " failed: " + ErrnoText(ret));
      }
      stream_ = stream.stream();
      stride_ = stream.stride;
      return;
    }
    Fail(HardwareError::Kind::kInvalidArgument, "camera.width/height: " + Name() +
                                                    " cannot deliver " + wanted_size.toString() +
                                                    " (" + refusals + ")");
  }

  // Allocates the stream's buffers, maps the plane each frame is read from, and makes
  // one request per buffer.
  void AllocateBuffers() {
    allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
    if (const int ret = allocator_->allocate(stream_); ret < 0) {
      Fail(HardwareError::Kind::kIo, Name() + ": allocating buffers failed: " + ErrnoText(ret));
    }
    for (const std::unique_ptr<lc::FrameBuffer>& buffer : allocator_->buffers(stream_)) {
      // Plane 0 is the grey image, the Y plane of YUV420, or the Bayer mosaic. Its offset
      // need not be page aligned, so the map starts at the file's beginning.
      const lc::FrameBuffer::Plane& plane = buffer->planes().at(0);
      const size_t offset =
          plane.offset == lc::FrameBuffer::Plane::kInvalidOffset ? 0 : plane.offset;
      const size_t length = offset + plane.length;
      void* address = mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      if (address == MAP_FAILED) {
        Fail(HardwareError::Kind::kIo,
             Name() + ": mapping a buffer failed: " + std::strerror(errno));
      }
      mappings_.push_back({address, length});
      planes_.push_back(
          {buffer.get(),
           std::span<const uint8_t>(static_cast<const uint8_t*>(address) + offset, plane.length)});
      std::unique_ptr<lc::Request> request = camera_->createRequest(requests_.size());
      if (!request) Fail(HardwareError::Kind::kIo, Name() + ": cannot create a request");
      if (const int ret = request->addBuffer(stream_, buffer.get()); ret < 0) {
        Fail(HardwareError::Kind::kIo,
             Name() + ": adding a buffer to a request failed: " + ErrnoText(ret));
      }
      requests_.push_back(std::move(request));
    }
  }

  // Stops the camera (if started) and frees what Start() made, in reverse order.
  void Release() {
    if (camera_started_) {
      // Cancels the queued requests; they complete, and are discarded, before it returns.
      camera_->stop();
      camera_started_ = false;
    }
    camera_->requestCompleted.disconnect(this);
    camera_->disconnected.disconnect(this);
    {
      std::lock_guard lock(mutex_);
      completed_.clear();
    }
    requests_.clear();
    planes_.clear();
    for (const Mapping& mapping : mappings_) munmap(mapping.address, mapping.length);
    mappings_.clear();
    if (allocator_ && stream_) allocator_->free(stream_);
    allocator_.reset();
    stream_ = nullptr;
    on_frame_ = nullptr;
    on_end_ = nullptr;
  }

  // libcamera's thread: only hand the request to ours.
  void OnRequestCompleted(lc::Request* request) {
    {
      std::lock_guard lock(mutex_);
      completed_.push_back(request);
    }
    wake_.notify_all();
  }

  void OnDisconnected() {
    {
      std::lock_guard lock(mutex_);
      disconnected_ = true;
    }
    wake_.notify_all();
  }

  // The camera's thread: turns completed requests into frames and queues them again.
  void Run() {
    // A sensor that stays silent for ten frame periods (at least a second) has stalled.
    const auto stall = std::max<std::chrono::microseconds>(
        std::chrono::seconds(1), std::chrono::microseconds(10 * controls_.frame_duration_us));
    try {
      while (true) {
        lc::Request* request = nullptr;
        {
          std::unique_lock lock(mutex_);
          const bool woke = wake_.wait_for(
              lock, stall, [&] { return stop_ || disconnected_ || !completed_.empty(); });
          if (stop_) return;
          if (disconnected_) Fail(HardwareError::Kind::kIo, Name() + " was disconnected");
          if (!woke) {
            Fail(HardwareError::Kind::kTimeout,
                 Name() + ": no frame for " + std::to_string(stall.count() / 1000) + " ms");
          }
          request = completed_.front();
          completed_.pop_front();
        }
        // The frame is copied out: the request goes back to the sensor before the frame
        // goes on.
        Frame frame = TakeFrame(request);
        request->reuse(lc::Request::ReuseBuffers);
        if (const int ret = camera_->queueRequest(request); ret < 0) {
          Fail(HardwareError::Kind::kIo, Name() + ": queueing a request failed: " + ErrnoText(ret));
        }
        if (frame.valid()) on_frame_(std::move(frame));
      }
    } catch (const HardwareError& error) {
      if (on_end_) on_end_(&error);
    } catch (const std::exception& e) {
      const HardwareError error(HardwareError::Kind::kIo, Name() + ": " + e.what());
      if (on_end_) on_end_(&error);
    }
  }

  // Copies a completed request's frame into a free pool buffer (FrameAssembler); an
  // invalid Frame when it is dropped (no free buffer, or a frame in error). The copy packs
  // the stride away and keeps libcamera's buffers always queued, so the consumer's pace
  // never stalls the sensor and Frame pixels outlive the camera.
  Frame TakeFrame(lc::Request* request) {
    if (request->status() == lc::Request::RequestCancelled) {
      Fail(HardwareError::Kind::kIo, Name() + ": the pipeline cancelled a request");
    }
    const lc::FrameBuffer* buffer = request->findBuffer(stream_);
    if (buffer == nullptr) {
      Fail(HardwareError::Kind::kIo, Name() + ": a request came back without its buffer");
    }
    const lc::FrameMetadata& metadata = buffer->metadata();
    // A frame in error is not delivered; the next good frame's sequence gap counts it.
    if (metadata.status != lc::FrameMetadata::FrameSuccess) return Frame();
    const lc::ControlList& result = request->metadata();
    const std::optional<int64_t> sensor_ns = result.get(lc::controls::SensorTimestamp);
    libcamera_stream::SensorFrame frame;
    frame.sensor_sequence = metadata.sequence;
    frame.plane = PlaneOf(buffer);
    frame.stride = stride_;
    // Without SensorTimestamp, the buffer's (V4L2) timestamp is already CLOCK_MONOTONIC.
    frame.timestamp_ns = sensor_ns ? libcamera_stream::SteadyNsFromBoottimeNs(*sensor_ns)
                                   : static_cast<int64_t>(metadata.timestamp);
    frame.exposure_us = result.get(lc::controls::ExposureTime).value_or(config_.exposure_us);
    frame.gain = result.get(lc::controls::AnalogueGain).value_or(static_cast<float>(config_.gain));
    libcamera_stream::FrameAssembler::Assembled assembled = assembler_->Assemble(frame);
    dropped_ += assembled.dropped;
    return std::move(assembled.frame);
  }

  std::span<const uint8_t> PlaneOf(const lc::FrameBuffer* buffer) const {
    for (const auto& [owner, plane] : planes_) {
      if (owner == buffer) return plane;
    }
    Fail(HardwareError::Kind::kIo, Name() + ": a buffer that was never allocated came back");
  }

  struct Mapping {
    void* address;
    size_t length;
  };

  // Declared first, destroyed last: the manager outlives the camera it made.
  std::shared_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  CameraConfig config_;
  libcamera_stream::SensorControls controls_;
  bool configured_ = false;

  // From Start() to Stop().
  lc::Stream* stream_ = nullptr;
  size_t stride_ = 0;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  std::vector<Mapping> mappings_;
  std::vector<std::pair<const lc::FrameBuffer*, std::span<const uint8_t>>> planes_;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  bool camera_started_ = false;
  std::optional<libcamera_stream::FrameAssembler> assembler_;
  FrameCallback on_frame_;
  EndCallback on_end_;
  std::thread worker_;
  std::atomic<uint64_t> dropped_{0};

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<lc::Request*> completed_;  // guarded by mutex_
  bool stop_ = false;                   // guarded by mutex_
  bool disconnected_ = false;           // guarded by mutex_
};

std::vector<std::string> ListCameras() { return CameraIds(*Manager()); }

std::unique_ptr<Camera> OpenCamera(const std::string& camera_id) {
  std::shared_ptr<lc::CameraManager> manager = Manager();
  std::shared_ptr<lc::Camera> camera = manager->get(camera_id);
  if (!camera) {
    Fail(HardwareError::Kind::kIo, "libcamera: no camera \"" + camera_id +
                                       "\"; cameras available: " + JoinIds(CameraIds(*manager)));
  }
  if (const int ret = camera->acquire(); ret < 0) {
    Fail(HardwareError::Kind::kIo,
         "libcamera: camera \"" + camera_id + "\" is in use elsewhere: " + ErrnoText(ret));
  }
  return std::make_unique<LibcameraCamera>(std::move(manager), std::move(camera));
}

}  // namespace
}  // namespace mirrorscan::hal

extern "C" __attribute__((visibility("default"))) const mirrorscan::hal::LibcameraModuleApi*
mirrorscan_camera_libcamera_module() {
  static const mirrorscan::hal::LibcameraModuleApi api{mirrorscan::hal::kLibcameraModuleAbiVersion,
                                                       &mirrorscan::hal::ListCameras,
                                                       &mirrorscan::hal::OpenCamera};
  return &api;
}

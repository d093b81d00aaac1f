// CPU time per frame of the firmware's capture → peaks → store path on the virtual
// board's frames (1024 × 768, the mannequin sweep), apart from the renderer, whose cost a
// real camera does not have:
//  - BM_RenderFrame: the renderer alone (the simulation's cost, for comparison).
//  - BM_CaptureToStore: one frame through what the sequencer does with it: a pool buffer
//    wrapped as a Frame, the capture queue, peak extraction with the virtual board's
//    parameters, the slide position lookup, the record queue and ScanHandle::AppendFrame
//    into a real store. CPU time per iteration = per frame, one thread.
//  - BM_SequencerScan: a whole 2 s scan by the Sequencer (replay cameras playing rendered
//    frames at 30 fps × 2, the simulated drive over Modbus TCP, virtual GPIO); reports the
//    process's CPU time per stored frame, which also counts the replay camera's file
//    reads, the drive simulator and the Modbus polling.
#include <benchmark/benchmark.h>

#include <time.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "boards/virtual/renderer.h"
#include "common/peaks/peaks.h"
#include "firmware/board/board_config.h"
#include "firmware/board/devices.h"
#include "firmware/board/virtual/linked_simulator.h"
#include "firmware/hal/camera.h"
#include "firmware/hal/replay/replay_camera.h"
#include "firmware/scan/bounded_queue.h"
#include "firmware/scan/drive_monitor.h"
#include "firmware/scan/sequencer.h"
#include "firmware/store/scan_store.h"
#include "tests/support/temp_dir.h"

namespace mirrorscan {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = MIRRORSCAN_SOURCE_DIR;

const virtual_cabinet::Renderer& Cabinet() {
  static const virtual_cabinet::Renderer renderer(
      virtual_cabinet::Scene::Load(kSource / "boards/virtual/scenes/mannequin.json"));
  return renderer;
}

// Frames of both cameras across the sweep.
const std::vector<virtual_cabinet::GrayImage>& Frames() {
  static const std::vector<virtual_cabinet::GrayImage> frames = [] {
    std::vector<virtual_cabinet::GrayImage> out;
    for (int camera = 0; camera < 2; ++camera) {
      for (int frame = 15; frame < 300; frame += 25) {
        out.push_back(Cabinet().RenderFrame(camera, frame / 30.0, static_cast<uint64_t>(frame)));
      }
    }
    return out;
  }();
  return frames;
}

const board::BoardConfig& VirtualBoard() {
  static const board::BoardConfig config =
      board::BoardConfig::Load(kSource / "boards/virtual/board.json");
  return config;
}

double ProcessCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

void BM_RenderFrame(benchmark::State& state) {
  Frames();  // the per-camera precomputation is not a frame's cost
  uint64_t index = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(Cabinet().RenderFrame(0, 4.0, index++));
  }
}
BENCHMARK(BM_RenderFrame)->Unit(benchmark::kMillisecond);

// A slide that only answers position queries, for the DriveMonitor.
class StillDrive final : public hal::SlideDrive {
 public:
  void Enable(bool) override {}
  void StartHome() override {}
  void SetSpeed(double) override {}
  void Start(double) override {}
  void ResetFault() override {}
  double Position() override { return 300.0; }
  hal::SlideStatus Status() override { return {}; }

 protected:
  void DoStop() override {}
};

void BM_CaptureToStore(benchmark::State& state) {
  const std::vector<virtual_cabinet::GrayImage>& frames = Frames();
  const int width = frames[0].width, height = frames[0].height;
  const int count = static_cast<int>(frames.size());
  auto pool = std::make_shared<hal::FramePool>(width, height, 4);
  const test_support::TempDir dir("scan_pipeline_benchmark");
  {
    auto store = store::ScanStore::Open(dir.path());
    auto handle = store->BeginScan({{"board", "benchmark"}});
    StillDrive drive;
    scan::DriveMonitor monitor(drive, std::chrono::milliseconds(10));
    scan::BoundedQueue<hal::Frame> capture_queue(8);
    scan::BoundedQueue<FrameRecord> record_queue(64);
    PeakExtractor extractor;
    const PeakParams& params = VirtualBoard().peaks;
    uint64_t sequence = 0;
    size_t peaks = 0;
    for (auto _ : state) {
      const int buffer = *pool->Acquire();
      const int index = static_cast<int>(sequence % count);
      state.PauseTiming();  // the sensor's DMA, not ours
      std::memcpy(pool->pixels(buffer), frames[index].pixels.data(), frames[index].pixels.size());
      state.ResumeTiming();
      hal::Frame frame =
          pool->MakeFrame(buffer, sequence, static_cast<int64_t>(sequence) * 33333333, 5000, 1.0);
      capture_queue.TryPush(frame);
      hal::Frame captured = *capture_queue.Pop();
      FrameRecord record;
      record.camera = index < count / 2 ? 0 : 1;
      record.sequence = static_cast<uint32_t>(sequence++);
      record.timestamp_ns = captured.timestamp_ns();
      record.lasers_on = true;
      record.slide_position_mm = monitor.PositionAt(record.timestamp_ns);
      extractor.Extract(captured.view(), params, &record.peaks);
      captured.Release();
      record_queue.TryPush(record);
      const FrameRecord stored = *record_queue.Pop();
      handle->AppendFrame(stored);
      peaks += stored.peaks.size();
    }
    handle->Finish({{"status", "complete"}});
    state.counters["peaks/frame"] =
        static_cast<double>(peaks) / static_cast<double>(state.iterations());
    state.counters["bytes/frame"] =
        static_cast<double>(handle->bytes()) / static_cast<double>(state.iterations());
  }
}
BENCHMARK(BM_CaptureToStore)->Unit(benchmark::kMillisecond);

void BM_SequencerScan(benchmark::State& state) {
  const test_support::TempDir dir("scan_pipeline_benchmark");
  // Replay cameras playing the rendered frames, so the renderer is not in the figure.
  board::BoardConfig config = VirtualBoard();
  config.scan.sweep_start_mm = 200;
  config.scan.sweep_end_mm = 500;
  const std::vector<virtual_cabinet::GrayImage>& frames = Frames();
  const size_t per_camera = frames.size() / 2;
  for (int c = 0; c < 2; ++c) {
    const fs::path frames_dir = dir / ("camera" + std::to_string(c));
    fs::create_directories(frames_dir);
    for (size_t i = 0; i < per_camera; ++i) {
      const auto& image = frames[c * per_camera + i];
      hal::WritePgm(frames_dir / (std::to_string(100 + i) + ".pgm"), image.width, image.height,
                    image.pixels.data());
    }
    config.cameras[c].backend = board::CameraBackend::kReplay;
    config.cameras[c].path = frames_dir;
  }
  board::DeviceOptions device_options;
  device_options.simulator = board::LinkedSimulator();
  board::BoardDevices devices = board::MakeBoardDevices(config, device_options);
  auto store = store::ScanStore::Open(dir / "data");
  scan::SequencerDevices sd;
  for (size_t i = 0; i < 2; ++i)
    sd.cameras.push_back({config.cameras[i].name, devices.cameras[i].get()});
  sd.lasers = devices.gpio.lasers.get();
  sd.led = devices.gpio.led.get();
  sd.drive = devices.drive.get();
  scan::SequencerOptions options;
  options.board = config.board;
  options.sweep_start_mm = config.scan.sweep_start_mm;
  options.sweep_end_mm = config.scan.sweep_end_mm;
  options.speed_mm_s = config.scan.speed_mm_s;
  options.peaks = config.peaks;
  scan::Sequencer sequencer(sd, *store, options);
  double cpu_s = 0.0;
  uint64_t stored = 0, dropped = 0;
  for (auto _ : state) {
    sequencer.StartScan("benchmark");
    while (sequencer.Status().state != scan::SequencerState::kSweeping) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const double cpu_before = ProcessCpuSeconds();
    while (sequencer.Status().state != scan::SequencerState::kDone &&
           sequencer.Status().state != scan::SequencerState::kFault) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    cpu_s += ProcessCpuSeconds() - cpu_before;
    stored += sequencer.Status().frames;
    dropped += sequencer.Status().dropped;
  }
  state.counters["cpu_ms/frame"] = cpu_s * 1e3 / static_cast<double>(stored);
  state.counters["frames"] = static_cast<double>(stored);
  state.counters["dropped"] = static_cast<double>(dropped);
}
BENCHMARK(BM_SequencerScan)->Iterations(2)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mirrorscan

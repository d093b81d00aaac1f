// Reconstruction speed: a whole 10 s, two-camera, three-laser sweep of the mannequin
// (docs/reconstruction.md) from the archive's bytes to the filtered, merged cloud, on the
// given number of threads (0: every core). The sweep is rendered once outside the timing, or read
// from MIRRORSCAN_BENCH_SCAN (an .mscan) with MIRRORSCAN_BENCH_CALIBRATION (its calibration).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "boards/virtual/renderer.h"
#include "boards/virtual/sweep_peaks.h"
#include "common/config/calibration.h"
#include "common/scan_format/scan_format.h"
#include "host/reconstruction/reconstruct.h"

namespace mirrorscan {
namespace {

struct Input {
  std::vector<uint8_t> archive;
  Calibration calibration;
  size_t peaks = 0;
};

Input Render() {
  const virtual_cabinet::Scene scene = virtual_cabinet::Scene::Load(
      std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/mannequin.json");
  const virtual_cabinet::Renderer renderer(scene);
  Input input;
  input.calibration = Calibration::Parse(scene.TrueCalibration(), "calibration.json");
  VectorSink sink;
  ScanWriter writer(sink);
  writer.Begin(virtual_cabinet::SweepArchiveHeader(scene));
  for (const FrameRecord& record : virtual_cabinet::RenderSweepPeaks(scene, renderer))
    writer.AppendFrame(record);
  writer.Finish({{"status", "complete"}});
  input.archive = sink.bytes();
  input.peaks = writer.peaks_written();
  return input;
}

const Input& Sweep() {
  static const Input input = [] {
    const char* scan = std::getenv("MIRRORSCAN_BENCH_SCAN");
    const char* calibration = std::getenv("MIRRORSCAN_BENCH_CALIBRATION");
    if (!scan || !calibration) return Render();
    Input in;
    // Sized read: GCC 12 warns of a null streambuf inside istreambuf_iterator here.
    std::ifstream file(scan, std::ios::binary | std::ios::ate);
    if (!file) throw std::runtime_error(std::string(scan) + ": cannot be read");
    in.archive.resize(static_cast<size_t>(file.tellg()));
    file.seekg(0);
    file.read(reinterpret_cast<char*>(in.archive.data()),
              static_cast<std::streamsize>(in.archive.size()));
    in.calibration = Calibration::Load(calibration);
    in.peaks = ReadScan(in.archive).report.peaks;
    return in;
  }();
  return input;
}

void BM_ReconstructSweep(benchmark::State& state) {
  const Input& input = Sweep();
  reconstruction::ReconstructOptions options;
  options.allow_calibration_mismatch = true;  // the calibration is given with the archive
  options.threads = static_cast<int>(state.range(0));
  size_t points = 0;
  for (auto _ : state) {
    const ScanArchive archive = ReadScan(input.archive);
    const reconstruction::Reconstruction r =
        reconstruction::Reconstruct(archive, input.calibration, options);
    points = r.cloud.points.size();
    benchmark::DoNotOptimize(r.cloud.points.data());
  }
  state.counters["peaks"] = static_cast<double>(input.peaks);
  state.counters["points"] = static_cast<double>(points);
  state.counters["peaks/s"] =
      benchmark::Counter(static_cast<double>(input.peaks) * static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReconstructSweep)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();

}  // namespace
}  // namespace mirrorscan

// Peak extraction throughput on 1024×768 frames of the virtual cabinet (the mannequin
// sweep, both cameras, default sensor), one core: the SIMD extractor, the scalar
// thresholded centre of mass (the paper's method) and a plain read of every byte.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <vector>

#include "boards/virtual/renderer.h"
#include "common/peaks/peaks.h"

namespace mirrorscan {
namespace {

const std::vector<virtual_cabinet::GrayImage>& Frames() {
  static const std::vector<virtual_cabinet::GrayImage> frames = [] {
    const virtual_cabinet::Renderer renderer(virtual_cabinet::Scene::Load(
        std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/mannequin.json"));
    std::vector<virtual_cabinet::GrayImage> out;
    for (int camera = 0; camera < 2; ++camera) {
      for (int frame = 15; frame < 300; frame += 25) {
        out.push_back(renderer.RenderFrame(camera, frame / 30.0, static_cast<uint64_t>(frame)));
      }
    }
    return out;
  }();
  return frames;
}

ImageView View(const virtual_cabinet::GrayImage& image) {
  return ImageView{image.pixels.data(), image.width, image.height, image.width};
}

void Report(benchmark::State& state, size_t total_peaks) {
  state.counters["frames/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["MB/s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * 1024 * 768 / 1e6, benchmark::Counter::kIsRate);
  state.counters["peaks/frame"] =
      static_cast<double>(total_peaks) / static_cast<double>(state.iterations());
}

// Argument 1: the defaults; 0: without the cross-column stage (no along-stripe smoothing,
// no stripe filters), i.e. columns only.
void BM_CabinetExtractSimd(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  if (state.range(0) == 0) {
    params.along_stripe_half_width = 0;
    params.drop_isolated_peaks = false;
    params.stripe_end_min_ratio = 0;
  }
  const auto& frames = Frames();  // rendered once, outside the timing
  size_t i = 0, total = 0;
  for (auto _ : state) {
    extractor.Extract(View(frames[i++ % frames.size()]), params, &peaks);
    total += peaks.size();
    benchmark::DoNotOptimize(peaks.data());
  }
  state.SetLabel(PeakExtractor::SimdTarget());
  Report(state, total);
}
BENCHMARK(BM_CabinetExtractSimd)->ArgName("cross_column")->Arg(1)->Arg(0);

void BM_CabinetScalarCentreOfMass(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  params.estimator = PeakEstimator::kThresholdedCom;
  const auto& frames = Frames();  // rendered once, outside the timing
  size_t i = 0, total = 0;
  for (auto _ : state) {
    extractor.ExtractScalar(View(frames[i++ % frames.size()]), params, &peaks);
    total += peaks.size();
    benchmark::DoNotOptimize(peaks.data());
  }
  Report(state, total);
}
BENCHMARK(BM_CabinetScalarCentreOfMass);

void BM_CabinetReadPass(benchmark::State& state) {
  const auto& frames = Frames();
  size_t i = 0;
  for (auto _ : state) {
    const auto& pixels = frames[i++ % frames.size()].pixels;
    const auto* p = reinterpret_cast<const uint64_t*>(pixels.data());
    uint64_t acc0 = 0, acc1 = 0, acc2 = 0, acc3 = 0;
    for (size_t k = 0; k + 4 <= pixels.size() / 8; k += 4) {
      acc0 ^= p[k];
      acc1 ^= p[k + 1];
      acc2 ^= p[k + 2];
      acc3 ^= p[k + 3];
    }
    benchmark::DoNotOptimize(acc0 ^ acc1 ^ acc2 ^ acc3);
  }
  Report(state, 0);
}
BENCHMARK(BM_CabinetReadPass);

}  // namespace
}  // namespace mirrorscan

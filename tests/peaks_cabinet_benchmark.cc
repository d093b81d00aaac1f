// Peak extraction throughput on 1024×768 frames of the virtual cabinet (the mannequin
// sweep, both cameras, default sensor, and the same with wide stripes), one core: the SIMD
// extractor, a plain row-major thresholded centre of mass (the fair reference), the
// paper's centre of mass on the project's scalar column walk and a plain read of every
// byte. scripts/peaks_speed runs it and prints the ratios.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <vector>

#include "boards/virtual/renderer.h"
#include "common/peaks/peaks.h"

namespace mirrorscan {
namespace {

// Argument "frames": 0 the cabinet's default frames; 1 wide stripes, the same sweep with
// the camera blur at 2.4 px (stripe sigma ~2.5 px, FWHM ~5.9 px: defocus, skin).
const std::vector<virtual_cabinet::GrayImage>& Frames(int64_t kind) {
  static std::vector<virtual_cabinet::GrayImage> frames[2];
  if (frames[kind].empty()) {
    auto scene = virtual_cabinet::Scene::Load(std::string(MIRRORSCAN_SOURCE_DIR) +
                                              "/boards/virtual/scenes/mannequin.json");
    if (kind == 1) scene.sensor.blur_px = 2.4;
    const virtual_cabinet::Renderer renderer(scene);
    for (int camera = 0; camera < 2; ++camera) {
      for (int frame = 15; frame < 300; frame += 25) {
        frames[kind].push_back(
            renderer.RenderFrame(camera, frame / 30.0, static_cast<uint64_t>(frame)));
      }
    }
  }
  return frames[kind];
}

// Above every unlit surface of these frames (ambient 40 DN x albedo: panels <= 32 DN) by
// the extractor's default threshold.
constexpr int kPlainThresholdDn = 50;

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
// no stripe filters), i.e. columns only; 2: the shipped boards' dim-stripe settings
// (threshold 10 DN, peaks under 18 DN only on stripes of 7 columns).
void BM_CabinetExtractSimd(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  if (state.range(1) == 0) {
    params.along_stripe_half_width = 0;
    params.drop_isolated_peaks = false;
    params.stripe_end_min_ratio = 0;
  } else if (state.range(1) == 2) {
    params.threshold_dn = 10;
    params.dim_peak_dn = 18;
    params.dim_stripe_min_columns = 7;
  }
  const auto& frames = Frames(state.range(0));  // rendered once, outside the timing
  size_t i = 0, total = 0;
  for (auto _ : state) {
    extractor.Extract(View(frames[i++ % frames.size()]), params, &peaks);
    total += peaks.size();
    benchmark::DoNotOptimize(peaks.data());
  }
  state.SetLabel(PeakExtractor::SimdTarget());
  Report(state, total);
}
BENCHMARK(BM_CabinetExtractSimd)
    ->ArgNames({"frames", "cross_column"})
    ->Args({0, 1})
    ->Args({0, 0})
    ->Args({0, 2})
    ->Args({1, 1});

// The fair reference: a plain row-major thresholded centre of mass (PlainCentreOfMass).
void BM_CabinetPlainCentreOfMass(benchmark::State& state) {
  PlainCentreOfMass plain;
  std::vector<Peak> peaks;
  const auto& frames = Frames(state.range(0));
  size_t i = 0, total = 0;
  for (auto _ : state) {
    plain.Extract(View(frames[i++ % frames.size()]), kPlainThresholdDn, &peaks);
    total += peaks.size();
    benchmark::DoNotOptimize(peaks.data());
  }
  Report(state, total);
}
BENCHMARK(BM_CabinetPlainCentreOfMass)->ArgName("frames")->Arg(0)->Arg(1);

// The paper's estimator on the project's own scalar column walk (candidates and
// refinement as ExtractScalar): not a plain implementation, see BM_CabinetPlainCentreOfMass.
void BM_CabinetScalarCentreOfMass(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  params.estimator = PeakEstimator::kThresholdedCom;
  const auto& frames = Frames(0);  // rendered once, outside the timing
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
  const auto& frames = Frames(0);
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
